"""The contract page (docs/reference/contract.md) names every DBC message and signal with the DBC's ID, sender,
cycle time, unit and range, so the page cannot drift from the DBC."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from dsg_hil.protocol import load_dbc

PAGE = Path(__file__).resolve().parents[2] / "docs" / "reference" / "contract.md"
HEADING = re.compile(r"^### 0x([0-9A-F]{3}) (\w+): (\w+) → (\w+), every (\d+) ms$", re.M)
ROW = re.compile(r"^\| `(\w+)` \| ([^|]*) \| (\S+) … (\S+) \| (.+) \|$", re.M)


def sections() -> dict[str, tuple[tuple[str, ...], str]]:
    text = PAGE.read_text(encoding="utf-8")
    found = list(HEADING.finditer(text))
    assert found, "contract page: no message headings"
    ends = [m.start() for m in found[1:]] + [text.index("\n## ", found[-1].end())]
    return {m.group(2): (m.groups(), text[m.end():end]) for m, end in zip(found, ends, strict=True)}


@pytest.mark.skipif(not PAGE.exists(), reason="the contract page is in the checkout and the sdist, not in the wheel")
def test_the_page_describes_every_message_and_signal_as_the_dbc_defines_it():
    db, pages = load_dbc(), sections()
    assert sorted(pages) == sorted(m.name for m in db.messages)
    for message in db.messages:
        (frame_id, _, sender, receiver, cycle), body = pages[message.name]
        assert (int(frame_id, 16), sender, int(cycle)) == (message.frame_id, message.senders[0], message.cycle_time)
        assert receiver in message.signals[0].receivers
        rows = {m.group(1): m.groups()[1:] for m in ROW.finditer(body)}
        assert list(rows) == [s.name for s in message.signals], message.name
        for signal in message.signals:
            unit, lo, hi, meaning = rows[signal.name]
            where = f"{message.name}.{signal.name}"
            assert unit.strip() == signal.unit, where
            assert (float(lo), float(hi)) == (signal.minimum, signal.maximum), where
            assert len(meaning.strip()) > 10, f"{where}: no meaning given"
