"""The frames of a short lock-step run (plant + ecu-stub in one process) on each matrix, bit for bit: the shipped DBC
(the dsg-hil scheme), the ARXML example (Profiles 5 and 11 from the ARXML) and the second matrix dct_fd (Profiles 5
and 11C, CAN FD, Motorola, a multiplexed message). The generated codec's frames are the reference codec's (cantools'
encode and decode, ``RunConfig(reference_codec=True)``), and every frame under an AUTOSAR profile, whoever sent it,
is autosar-e2e's frame of its own data: a second implementation of the profiles' headers and CRCs (C), against
which the table-driven CRCs of :mod:`dsg_hil.protocol.crc` cannot drift."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

import can
import pytest

from dsg_hil.protocol.profiles import FrameProtection, ProfileP01, ProfileP02, ProfileP05
from dsg_hil.sim.run import RunConfig, open_run

e2e = pytest.importorskip("e2e", reason="autosar-e2e (the test extra) is the second implementation")

EXAMPLES = resources.files("dsg_hil") / "data" / "examples"
MATRICES = {
    "shipped": (None, None),
    "arxml": (Path(str(EXAMPLES / "arxml" / "tcu.arxml")), Path(str(EXAMPLES / "arxml" / "tcu.binding.toml"))),
    "dct_fd": (Path(str(EXAMPLES / "dct_fd" / "dct_fd.dbc")), Path(str(EXAMPLES / "dct_fd" / "dct_fd.binding.toml"))),
}
DURATION = 3.0  # s of the default creep: CL engaged, its pressure and the plate's temperature moving


def _frames(dbc: Path | None, binding: Path | None, reference: bool) -> tuple[list[can.Message], dict, dict]:
    """The frames the plant sent and took, the plant's protections and message lengths by frame ID."""
    with open_run(RunConfig(duration=DURATION, dbc=dbc, binding=binding, capture=True,
                            reference_codec=reference)) as run:
        summary = run.run().as_json()
        codec = run.runner.codec
    assert summary["frames"]["rejected"] == summary["frames"]["lost"] == 0
    protections = {codec.frame_id(name): p for name, p in codec.protections().items()}
    lengths = {codec.frame_id(name): codec.message(name).length for name in codec.protections()}
    return run.frames, protections, lengths


def _bits(frames: list[can.Message]) -> list[tuple[int, bool, bool, bytes]]:
    return [(f.arbitration_id, f.is_fd, f.bitrate_switch, bytes(f.data)) for f in frames]


def _theirs(protection: FrameProtection, data: bytes) -> bytes | None:
    """autosar-e2e's frame of ``data`` (its counter in place) under ``protection``; None: not an AUTOSAR profile."""
    raw = bytearray(data)
    if isinstance(protection, ProfileP05):
        e2e.p05.e2e_p05_protect(raw, protection.data_id, length=protection.data_length // 8,
                                offset=protection.crc_offset // 8, increment_counter=False)
    elif isinstance(protection, ProfileP01):
        assert protection.counter_offset == protection.crc_offset + 8  # (autosar-e2e's fixed relative layout)
        module, prefix = (e2e.p11, "E2E_P11") if protection.profile == "P11" else (e2e.p01, "E2E_P01")
        mode = getattr(module, f"{prefix}_DATAID_{protection.data_id_mode.upper()}")
        protect = module.e2e_p11_protect if protection.profile == "P11" else module.e2e_p01_protect
        protect(raw, protection.data_id, data_id_mode=mode, length=protection.data_length // 8,
                offset=protection.crc_offset // 8, increment_counter=False)
    elif isinstance(protection, ProfileP02):
        e2e.p02.e2e_p02_protect(raw, protection.data_ids, length=protection.data_length // 8,
                                increment_counter=False)
    else:
        return None
    return bytes(raw)


@pytest.fixture(scope="module", params=list(MATRICES))
def runs(request):
    dbc, binding = MATRICES[request.param]
    return request.param, _frames(dbc, binding, False), _frames(dbc, binding, True)


def test_the_generated_codecs_frames_are_the_reference_codecs(runs):
    _, (generated, *_), (reference, *_) = runs
    assert len(generated) >= 500 * DURATION  # (the plant's frames and the TCU's)
    assert _bits(generated) == _bits(reference)


def test_every_profiled_frame_is_autosar_e2es(runs):
    name, (frames, protections, lengths), _ = runs
    checked: dict[str, int] = {}
    for frame in frames:
        protection = protections[frame.arbitration_id]
        data = bytes(frame.data)[:lengths[frame.arbitration_id]]  # (a CAN FD frame's padding apart)
        theirs = _theirs(protection, data)
        if theirs is not None:
            assert theirs == data, (name, hex(frame.arbitration_id), data.hex())
            checked[protection.profile] = checked.get(protection.profile, 0) + 1
    expected = {"shipped": set(), "arxml": {"P05", "P11"}, "dct_fd": {"P05", "P11"}}[name]
    assert set(checked) == expected
    assert all(n >= 10 * DURATION for n in checked.values())  # (every cycle of the slowest message, 10 Hz)
