"""``dsg-hil binding init DB``: a binding's skeleton for a database. Every quantity of the plant is listed (the ones it
needs marked), under each the signals that can carry it; on the example matrices the signal their bindings chose is
among them, the skeleton is TOML, and filled in with those choices it passes the binding check. A quantity no
signal can carry gets the closest ones with the reason."""

from __future__ import annotations

import re
import tomllib
from importlib import resources
from pathlib import Path

import cantools
import pytest

from dsg_hil.cli import main
from dsg_hil.protocol import load_dbc
from dsg_hil.protocol.binding import QUANTITIES, check_binding
from dsg_hil.protocol.skeleton import binding_skeleton, free_simulation_ids, guess_values

EXAMPLES = Path(str(resources.files("dsg_hil") / "data" / "examples"))
PAIRS = {"dct_fd": (EXAMPLES / "dct_fd" / "dct_fd.dbc", EXAMPLES / "dct_fd" / "dct_fd.binding.toml"),
         "arxml": (EXAMPLES / "arxml" / "tcu.arxml", EXAMPLES / "arxml" / "tcu.binding.toml")}


def offered(text: str) -> dict[str, list[str]]:
    """By quantity, the signals the skeleton offers (its commented-out lines)."""
    out: dict[str, list[str]] = {}
    for quantity, ref in re.findall(r'^#(\w+) = "(\w+\.\w+)"', text, re.M):
        out.setdefault(quantity, []).append(ref)
    return out


@pytest.mark.parametrize("name", sorted(PAIRS))
def test_the_skeleton_offers_the_example_bindings_signals(name):
    dbc, binding = PAIRS[name]
    text = binding_skeleton(load_dbc(dbc), dbc.name)
    skeleton = tomllib.loads(text)
    assert skeleton["send"] == skeleton["read"] == [] and skeleton["quantities"] == {}
    for quantity, spec in QUANTITIES.items():
        heading = f"# {quantity} (required): " if spec.required else f"# {quantity}: "
        assert f"\n{heading}" in text, quantity
    chosen = {q: (r if isinstance(r, str) else r["signal"])
              for q, r in tomllib.loads(binding.read_text(encoding="utf-8"))["quantities"].items()}
    assert len(chosen) >= 30
    offers = offered(text)
    for quantity, ref in chosen.items():
        assert ref in offers[quantity], (quantity, offers.get(quantity))
    assert 'echo = "MESSAGE.Signal"' in text


def test_the_skeleton_filled_with_the_bindings_choices_passes_the_check(tmp_path):
    """The ARXML's skeleton, its choices uncommented (the example binding's), send/read and the echo filled in:
    binding check passes on it, with the skeleton's [simulation] IDs."""
    dbc, binding = PAIRS["arxml"]
    example = tomllib.loads(binding.read_text(encoding="utf-8"))
    text = binding_skeleton(load_dbc(dbc), dbc.name)
    for quantity, ref in example["quantities"].items():
        text = text.replace(f'#{quantity} = "{ref}"', f'{quantity} = "{ref}"', 1)
    text = text.replace("send = []", f"send = {example['send']!r}".replace("'", '"'))
    text = text.replace("read = []", f"read = {example['read']!r}".replace("'", '"'))
    text = text.replace('echo = "MESSAGE.Signal"', 'echo = "TCU_CMD.SyncEcho"')
    (tmp_path / "b.toml").write_text(text, encoding="utf-8")
    found, problems = check_binding(tmp_path / "b.toml", dbc=dbc)
    assert problems == [] and found is not None and set(found.units) == set(example["quantities"])
    (tmp_path / "raw.toml").write_text(binding_skeleton(load_dbc(dbc), dbc.name), encoding="utf-8")
    raw, problems = check_binding(tmp_path / "raw.toml", dbc=dbc)  # as printed: the echo is the first thing to give
    assert raw is None and problems[-1].endswith("lockstep.echo: message MESSAGE is not in the database")


HOT = """VERSION ""
BS_:
BU_: TCU PLANT
BO_ 512 CMD: 8 TCU
 SG_ T_Pred : 0|8@1+ (1,-40) [-40|200] "degC" PLANT
 SG_ Oil : 8|16@1+ (0.1,-40) [-40|400] "degC" PLANT
"""


def test_a_quantity_no_signal_carries_gets_the_closest_with_the_reason():
    """A predicted plate temperature signal ending at 200 degC (the plates reach 350): not offered as carrying
    it, shown as the closest with its range; the oil signal (to 400 degC in 0.1 steps) offered."""
    db = cantools.database.load_string(HOT, "dbc")
    text = binding_skeleton(db, "hot.dbc")
    block = text.split("# T_CL_pred (required)")[1].split("\n# T_CH_pred")[0]
    assert block.splitlines()[1] == '#T_CL_pred = "CMD.Oil"  # degC, no cycle time, from TCU'
    oil = text.split("# T_oil_CL:")[1].split("\n# T_oil_CH")[0]
    assert "#   (no signal can carry it; the closest:)" not in block
    assert '#T_oil_CL = "CMD.Oil"' in oil and "CMD.T_Pred" not in oil  # T_Pred's 1 degC steps: oil needs 0.5
    narrow = binding_skeleton(cantools.database.load_string(HOT.replace(' SG_ Oil', ' SG_ X_Oil').replace(
        '[-40|400] "degC"', '[-40|300] "degC"'), "dbc"), "hot.dbc")
    block = narrow.split("# T_CL_pred (required)")[1].split("\n# T_CH_pred")[0]
    assert "#   (no signal can carry it; the closest:)" in block
    assert "carries -40..200 degC, T_CL_pred needs -40..350 degC" in block


def test_free_simulation_ids():
    """The shipped DBC has the simulation messages: none added. A matrix on the simulation IDs: others, free."""
    assert free_simulation_ids(load_dbc()) == {}
    db = cantools.database.load_string(HOT.replace("BO_ 512", "BO_ 2032"), "dbc")
    ids = free_simulation_ids(db)
    assert set(ids) == {"SIM_SYNC", "SIM_TRUTH_CL", "SIM_TRUTH_CH", "SIM_HEAT"} and 2032 not in ids.values()
    assert len(set(ids.values())) == 4 and ids["SIM_TRUTH_CL"] == 1792


def test_binding_init_prints_the_skeleton(capsys):
    dbc, _ = PAIRS["dct_fd"]
    assert main(["binding", "init", str(dbc)]) == 0
    out = capsys.readouterr().out
    assert out == binding_skeleton(load_dbc(dbc), str(dbc))


def values_lines(text: str, quantity: str) -> dict[str, str]:
    """By signal, the skeleton's commented-out entry of ``quantity`` with ``values`` (the line without its '#')."""
    return {m.group(2): m.group(1) for m in re.finditer(rf'^#({quantity} = {{ signal = "(\w+\.\w+)", values = .*)$',
                                                         text, re.M)}


def test_a_state_signal_with_a_value_table_gets_its_values_entry(tmp_path):
    """dct_fd renumbered (tests/sim/test_second_matrix.py: its GbxState 0 'Fault' .. 5 'ThermalStop', ActClutch
    0 'ClutchA', 1 'ClutchB', 2 'Open'): under GbxState, its entry with the TCU's names, the table's guessed by name
    ('?' for STOPPED_OVERHEAT, which 'ThermalStop' does not spell), and its numbers; ActClutch's names guess none.
    Uncommented, each '?' given and the plain entries replaced, the binding checks with the numbers of the variant's
    own binding. On the shipped DBC the tables are the TCU's numbering: the entry says values may stay out."""
    from tests.sim.test_second_matrix import NAMES, renumbered

    dbc, _ = renumbered(tmp_path)
    text = binding_skeleton(load_dbc(dbc), dbc.name)
    state, clutch = values_lines(text, "tcu_state"), values_lines(text, "active_clutch")
    assert set(state) == {"TCU_Info.GbxState"} and set(clutch) == {"TCU_Info.ActClutch", "TCU_Info.GbxState"}
    line = state["TCU_Info.GbxState"]
    assert 'values = { IDLE = "Idle", ENGAGE = "Engaging", CREEP = "Creeping", HANDOVER = "Handover", ' \
           'STOPPED_OVERHEAT = "?", FAULT = "Fault" } }' in line
    assert "# its values: 0 Fault, 1 Idle, 2 Engaging, 3 Creeping, 4 Handover, 5 ThermalStop; give the table's " \
           'name of each "?", check the ones guessed' in line
    assert 'values = { NONE = "?", CL = "?", CH = "?" }' in clutch["TCU_Info.ActClutch"]
    filled = (line.split("  #")[0].replace('"?"', '"ThermalStop"') + "\n"
              + clutch["TCU_Info.ActClutch"].split("  #")[0].replace('NONE = "?", CL = "?", CH = "?"',
                                                                   'NONE = "Open", CL = "ClutchA", CH = "ClutchB"'))
    assert tomllib.loads(filled) == tomllib.loads(NAMES)
    _, plain = renumbered(tmp_path, None)
    lines = plain.read_text(encoding="utf-8")
    (tmp_path / "filled.toml").write_text(lines.replace(
        'tcu_state = "TCU_Info.GbxState"\nactive_clutch = "TCU_Info.ActClutch"\n', filled + "\n"), encoding="utf-8")
    found, problems = check_binding(tmp_path / "filled.toml", dbc=dbc)
    assert problems == [] and found is not None
    assert found.values == {"tcu_state": {0: 1, 1: 2, 2: 3, 3: 4, 4: 5, 5: 0}, "active_clutch": {0: 2, 1: 0, 2: 1}}
    shipped = binding_skeleton(load_dbc(), "dsg_hil.dbc")
    for quantity, ref in (("tcu_state", "TCU_STATUS.State"), ("active_clutch", "TCU_STATUS.ActiveClutch")):
        assert values_lines(shipped, quantity)[ref].endswith("numbered as the TCU numbers them: values may stay out")
    assert "values = " not in text.split("# brake_request")[1]  # the state and clutch only


@pytest.mark.parametrize("choices, expected", [
    ({0: "Off", 1: "Starting", 2: "Crawl", 3: "HandOver", 4: "Stopped_Overheat", 5: "Error"},
     {"IDLE": "?", "ENGAGE": "?", "CREEP": "?", "HANDOVER": "HandOver", "STOPPED_OVERHEAT": "Stopped_Overheat",
      "FAULT": "?"}),
    ({0: "Idle", 1: "Idle2", 2: "Creep", 3: "CreepSlow", 4: "x", 5: "y"},  # the same name before a longer one
     {"IDLE": "Idle", "ENGAGE": "?", "CREEP": "Creep", "HANDOVER": "?", "STOPPED_OVERHEAT": "?", "FAULT": "?"}),
    ({0: "Engage_A", 1: "Engage_B", 2: "a", 3: "b", 4: "c", 5: "d"},  # ENGAGE: two as near, none guessed
     {"IDLE": "?", "ENGAGE": "?", "CREEP": "?", "HANDOVER": "?", "STOPPED_OVERHEAT": "?", "FAULT": "?"}),
])
def test_guess_values(choices, expected):
    """The names guessed: the same but for case and punctuation, else the one alone sharing the longest start
    (four letters at least); '?' else."""
    assert guess_values("tcu_state", choices) == expected
