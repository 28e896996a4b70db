"""The C a vendor starts from: ``cantools generate_c_source`` on the packaged DBC compiles with gcc, and its
pack/unpack functions agree with cantools' Python encoding on the contract's worked example frames (every
message: unsigned, signed, offset and odd-length signals, the counter and CRC bytes).

The generated ``..._encode(double)`` functions truncate toward zero where dsg-hil and cantools' Python round
(104.2 degC at 0.1/-40 gives raw 1441, not 1442): docs/reference/contract.md tells vendors to round; here they
are held to one raw step, and the frames are packed from the raw values."""

from __future__ import annotations

import shutil
import subprocess
import sys
from typing import cast
from importlib import resources

import pytest

from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.codec import DEFAULT_DBC
from dsg_hil.protocol.examples import example_frames

pytestmark = pytest.mark.skipif(shutil.which("gcc") is None, reason="gcc is not installed: the generated C cannot "
                                                                   "be compiled here")


def snake(name: str) -> str:
    from cantools.database.can.c_source import camel_to_snake_case

    return camel_to_snake_case(name)


def main_c(frames) -> str:
    """A C program that, per example frame, packs the raw values of the example with the generated functions and
    prints the bytes, prints what ``_encode`` makes of each physical value, then unpacks the example's bytes and
    prints every decoded physical value."""
    lines = ['#include <stdio.h>', '#include "dsg_hil.h"', "int main(void) {", "    uint8_t buf[8];"]
    for name, _, values, data in frames:
        message, prefix = load_dbc().get_message_by_name(name), f"dsg_hil_{snake(name)}"
        raw = cast(dict[str, int], message.decode(data, decode_choices=False, scaling=False))  # unscaled: ints
        lines += ["    {", f"        struct {prefix}_t m;", f"        {prefix}_init(&m);"]
        for signal in message.signals:
            field = snake(signal.name)
            lines.append(f"        m.{field} = {int(raw[signal.name])};")
            if signal.name in values:
                lines.append(f'        printf("{name}.{signal.name}.encode %lld\\n", '
                             f"(long long){prefix}_{field}_encode({float(values[signal.name])!r}));")
        lines += [f"        if ({prefix}_pack(buf, &m, sizeof buf) != 8) return 1;",
                  f'        printf("{name}");', '        for (int i = 0; i < 8; i++) printf(" %02X", buf[i]);',
                  '        printf("\\n");',
                  "        const uint8_t in[8] = {" + ", ".join(f"0x{b:02X}" for b in data) + "};",
                  f"        if ({prefix}_unpack(&m, in, sizeof in) != 0) return 2;"]
        for signal in message.signals:
            field = snake(signal.name)
            lines.append(f'        printf("{name}.{signal.name} %.17g\\n", {prefix}_{field}_decode(m.{field}));')
        lines.append("    }")
    return "\n".join([*lines, "    return 0;", "}", ""])


@pytest.mark.slow
def test_generated_c_compiles_and_packs_and_unpacks_as_cantools(tmp_path):
    with resources.as_file(DEFAULT_DBC) as dbc:
        subprocess.run([sys.executable, "-m", "cantools", "generate_c_source", str(dbc), "--output-directory",
                        str(tmp_path)], check=True, capture_output=True)
    db = load_dbc()
    frames = example_frames(db)
    assert [name for name, *_ in frames] == [m.name for m in db.messages]  # an example for every message
    (tmp_path / "main.c").write_text(main_c(frames), encoding="utf-8")
    exe = tmp_path / "check"
    build = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-o", str(exe), "main.c",
                            "dsg_hil.c"], cwd=tmp_path, capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
    run = subprocess.run([str(exe)], capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    printed = dict(line.split(" ", 1) for line in run.stdout.splitlines())
    for name, _, values, data in frames:
        message = db.get_message_by_name(name)
        decoded = message.decode(data, decode_choices=False)
        python = message.encode(decoded, strict=True)  # cantools' Python encoding of the same values
        assert python == data  # (and the codec's, which adds counter and CRC)
        assert printed[name] == " ".join(f"{b:02X}" for b in python), name  # C pack == Python encode
        raw = message.decode(data, decode_choices=False, scaling=False)
        for signal in message.signals:  # C unpack == Python decode
            where = f"{name}.{signal.name}"
            assert float(printed[where]) == pytest.approx(decoded[signal.name], abs=1e-9), where
            if signal.name in values:  # C encode truncates: within one raw step of Python's rounding
                assert abs(int(printed[f"{where}.encode"]) - int(raw[signal.name])) <= 1, where
