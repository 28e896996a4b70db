"""The guides' shell blocks run as a user types them (the programs on PATH, a directory of their own), and what the
pages show them print is what they print: the fault guide's run, the interfaces guide's two-process run and its two
sides started by hand, the diagnostics command's session, the binding check, the XCP guide's A2L, the layout's
tree. On udp_multicast a fresh group and port replace the page's, so that two runs on one host do not meet. Numbers
are compared as the quick start's are (test_blocks.same_line: one unit of the last printed digit). Skipped without a
checkout (an installed package has no docs/). tests/docs/test_inventory.py lists which test runs which block."""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import tomllib
from pathlib import Path

import pytest

from .test_blocks import BIN, ROOT, same_line

pytestmark = pytest.mark.skipif(not (ROOT / "mkdocs.yml").exists(), reason="the docs are in the checkout only")
ENV = {**os.environ, "PATH": f"{BIN}{os.pathsep}{os.environ.get('PATH', '')}"}


def blocks(page: str, language: str) -> list[str]:
    text = (ROOT / page).read_text(encoding="utf-8")
    return re.findall(rf"^```{language}\n(.*?)^```", text, re.S | re.M)


def sh_block(page: str, start: str) -> list[str]:
    """The command lines of the page's sh block that starts so (comments kept out)."""
    (block,) = [b for b in blocks(page, "sh") if b.startswith(start)]
    return [line for line in block.splitlines() if line.strip()]


def run(line: str, cwd: Path, replace: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """One command line of a page, as a shell would split it (a trailing comment dropped), words replaced."""
    words = [(replace or {}).get(word, word) for word in shlex.split(line, comments=True)]
    return subprocess.run(words, cwd=cwd, capture_output=True, text=True, timeout=600, env=ENV)


def check_shown(shown: str, printed: str) -> None:
    """Every line the page shows (but '...') is a line printed, in that order."""
    lines = printed.splitlines()
    at = 0
    for line in shown.splitlines():
        if line.strip() == "...":
            continue
        hits = [i for i in range(at, len(lines)) if same_line(line, lines[i])]
        assert hits, f"shown {line!r}, not printed after line {at}:\n{printed}"
        at = hits[0] + 1


def udp_words(page_channel: str, page_port: str) -> dict[str, str]:
    from dsg_hil.protocol.bus import fresh_udp_group

    group = fresh_udp_group()
    return {page_channel: group["channel"], f"port={page_port}": f"port={group['port']}"}


# -- faults, interfaces ----------------------------------------------------------------------------------------

@pytest.mark.slow
def test_the_fault_guide_s_run_runs(tmp_path: Path) -> None:
    """Its first line: two faults on the in-process loop; the run counts them (the other two lines need a real
    bus and vcan0: parsed by test_blocks.py)."""
    line = sh_block("docs/how-to/faults.md", "dsg-hil run")[0]
    done = run(line, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "t=10.00 s: lock-step tick 1000 unanswered" in done.stderr
    assert "t=12.000 s: valid TCU_CMD again" in done.stderr
    faults = json.loads((tmp_path / "s.json").read_text(encoding="utf-8"))["faults"]
    assert faults["seed"] == 7 and set(faults["injected"]) == {"drop:TCU_CMD@10-12",
                                                               "stuck:PLANT_VEHICLE.VehicleSpeed@40-45"}
    assert all(count > 0 for count in faults["injected"].values())


@pytest.mark.slow
def test_the_interfaces_guide_s_run_runs(tmp_path: Path) -> None:
    (line,) = sh_block("docs/how-to/interfaces.md", "dsg-hil run -i udp_multicast")
    done = run(line, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    summary = json.loads((tmp_path / "s.json").read_text(encoding="utf-8"))
    assert summary["frames"]["rejected"] == 0 and (tmp_path / "run.log").stat().st_size > 0


@pytest.mark.slow
def test_the_interfaces_guide_s_two_sides_start_as_shown(tmp_path: Path) -> None:
    """The plant started as shown prints its line and the TCU's command (with its own group and port); that
    command, run, answers its ticks: the plant's first progress line comes. Both are then stopped."""
    lines = sh_block("docs/how-to/interfaces.md", "$ dsg-hil plant")
    commands = [line.removeprefix("$ ") for line in lines if line.startswith("$ ")]
    shown = [line for line in lines if not line.startswith("$ ")]
    assert commands[0] == "dsg-hil plant -i udp_multicast --mode lockstep" and len(shown) == 2
    plant = subprocess.Popen(shlex.split(commands[0]), cwd=tmp_path, stderr=subprocess.PIPE, text=True, env=ENV)
    tcu = None
    try:
        assert plant.stderr is not None
        printed = [plant.stderr.readline().rstrip("\n") for _ in shown]
        address = re.compile(r"239\.255\.\d+\.\d+|port[= ]\d+")
        for line, got in zip(shown, printed):
            assert address.sub("#", line) == address.sub("#", got), (line, got)
        tcu_line = printed[1].removeprefix("TCU: ")
        page_tcu = shlex.split(commands[1], comments=True)
        assert address.sub("#", shlex.join(page_tcu)) == address.sub("#", tcu_line)
        tcu = subprocess.Popen(shlex.split(tcu_line), cwd=tmp_path, stderr=subprocess.DEVNULL, env=ENV)
        progress = ""
        while not progress.startswith("t="):
            progress = plant.stderr.readline()
            assert progress, "the plant ended before its first progress line"
    finally:
        for proc in (plant, tcu):
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGINT)
        for proc in (plant, tcu):
            if proc is not None:
                try:
                    proc.wait(timeout=60)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait()


# -- diagnostics ------------------------------------------------------------------------------------------------

@pytest.mark.slow
def test_the_diag_guide_s_session_prints_what_it_shows(tmp_path: Path) -> None:
    """ecu-stub in the background, the plant with its stuck speed, then the tester's dtc, read, clear and dtc: each
    prints the page's output (the freeze frame's numbers within their last digit)."""
    pytest.importorskip("udsoncan")
    page = "docs/how-to/diag-command.md"
    words = udp_words("239.255.12.34", "40000")
    (ecu_line,) = sh_block(page, "ecu-stub")
    plant_line, dtc_line = sh_block(page, "dsg-hil plant")
    (read_line,) = sh_block(page, "dsg-hil diag read")
    clear_line, again_line = sh_block(page, "dsg-hil diag clear")
    texts = blocks(page, "text")
    argv = [words.get(w, w) for w in shlex.split(ecu_line)]
    ecu = subprocess.Popen(argv, cwd=tmp_path, stderr=subprocess.PIPE, text=True, env=ENV)
    try:
        assert ecu.stderr is not None and "listening on udp_multicast" in ecu.stderr.readline()
        plant = run(plant_line, tmp_path, words)
        assert plant.returncode == 0, plant.stderr[-2000:]
        outputs = [run(line, tmp_path, words) for line in (dtc_line, read_line, clear_line, again_line)]
        assert [o.returncode for o in outputs] == [0, 0, 0, 0], [o.stderr[-500:] for o in outputs]
    finally:
        ecu.send_signal(signal.SIGTERM)
        ecu.communicate(timeout=60)
    dtc_shown, read_shown, cleared_shown = (t for t in texts if t.startswith(("DTC ", "0x0102", "cleared")))
    check_shown(dtc_shown, outputs[0].stdout)
    check_shown(read_shown, outputs[1].stdout)
    check_shown(cleared_shown, outputs[2].stdout + outputs[3].stdout)


def test_the_diag_guide_s_description_loads(tmp_path: Path) -> None:
    """The page's description of another ECU is one the command reads: its IDs, DIDs, snapshot and DTC."""
    from dsg_hil.protocol.diag import load_description

    (block,) = [b for b in blocks("docs/how-to/diag-command.md", "toml") if b.startswith("request_id")]
    path = tmp_path / "my_ecu.toml"
    path.write_text(block, encoding="utf-8")
    description = load_description(path)
    assert sorted(description.dids) == [0x0110, 0xF189] and list(description.snapshot) == [0x0110]
    assert [d.code for d in description.dtcs] == ["P0715"]


# -- binding, XCP, layout ---------------------------------------------------------------------------------------

def test_the_binding_guide_s_file_is_a_binding() -> None:
    """The page's file (for another DBC, not shipped) has the shipped binding's sections and quantities the plant
    knows, each a 'MESSAGE.Signal' or a table with one."""
    from dsg_hil.protocol.binding import DEFAULT_BINDING, QUANTITIES

    (block,) = [b for b in blocks("docs/how-to/binding.md", "toml") if b.startswith("send = [")]
    shown = tomllib.loads(block)
    shipped = tomllib.loads(DEFAULT_BINDING.read_text(encoding="utf-8"))
    assert set(shown) - {"messages"} <= set(shipped) and set(shown["lockstep"]) == set(shipped["lockstep"])
    assert set(shown["quantities"]) <= set(QUANTITIES)
    for ref in shown["quantities"].values():
        signal_ref = ref["signal"] if isinstance(ref, dict) else ref
        assert re.fullmatch(r"\w+\.\w+", signal_ref) and signal_ref.split(".")[0] in shown["send"] + shown["read"]


def test_the_binding_check_prints_the_guide_s_columns(tmp_path: Path) -> None:
    """The output the page shows is the check of the shipped DBC and binding (the command as on the page, with
    those two files)."""
    (line,) = sh_block("docs/how-to/binding.md", "dsg-hil binding check my_ecu")
    done = run(line, tmp_path, {"my_ecu.dbc": str(ROOT / "dbc" / "dsg_hil.dbc"),
                                "my_ecu.binding.toml": str(ROOT / "dbc" / "dsg_hil.binding.toml")})
    assert done.returncode == 0, done.stderr
    (shown,) = [b for b in blocks("docs/how-to/binding.md", "text") if b.startswith("quantity")]
    check_shown(shown, done.stdout)


def test_the_binding_check_prints_the_guide_s_values(tmp_path: Path) -> None:
    """The values table the page shows is the check's of a matrix numbering the TCU's states and clutches otherwise
    (the renumbered dct_fd of tests/sim/test_second_matrix.py, its binding naming them), the command as on the
    page."""
    from tests.sim.test_second_matrix import renumbered

    (line,) = sh_block("docs/how-to/binding.md", "dsg-hil binding check my_ecu")
    dbc, binding = renumbered(tmp_path)
    done = run(line, tmp_path, {"my_ecu.dbc": str(dbc), "my_ecu.binding.toml": str(binding)})
    assert done.returncode == 0, done.stderr
    (shown,) = [b for b in blocks("docs/how-to/binding.md", "text") if b.startswith("values")]
    check_shown(shown, done.stdout)


@pytest.mark.slow
def test_the_binding_guide_s_run_moves_both_ends(tmp_path: Path) -> None:
    """Its first line with another matrix and its binding for my_ecu's (the renamed pair of
    tests/sim/test_binding_run.py: every name and ID other, km/h, kPa, K): the in-process ecu-stub on that matrix
    creeps as on the shipped pair, nothing rejected (the ecu-stub line needs vcan0: parsed by test_blocks.py)."""
    from tests.sim.test_binding_run import write_renamed_pair

    line = sh_block("docs/how-to/binding.md", "dsg-hil run --dbc my_ecu.dbc")[0]
    dbc, binding = write_renamed_pair(tmp_path)
    other = run(line, tmp_path, {"my_ecu.dbc": str(dbc), "my_ecu.binding.toml": str(binding)})
    assert other.returncode == 0, other.stderr[-2000:]
    theirs = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    shipped = run(line, tmp_path, {"my_ecu.dbc": str(ROOT / "dbc" / "dsg_hil.dbc"),
                                   "my_ecu.binding.toml": str(ROOT / "dbc" / "dsg_hil.binding.toml")})
    assert shipped.returncode == 0, shipped.stderr[-2000:]
    ours = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    assert "TCU_Command" in theirs["frames"]["by_message"] and theirs["frames"]["rejected"] == 0
    assert theirs["frames"]["by_message"]["TCU_Command"]["taken"] > 0
    assert len(theirs["handovers"]) == len(ours["handovers"]) >= 1
    assert theirs["max_plate_temp_c"].keys() == ours["max_plate_temp_c"].keys()
    assert all(abs(theirs["max_plate_temp_c"][k] - t) < 0.01 for k, t in ours["max_plate_temp_c"].items())
    assert abs(theirs["creep_time_s"] - ours["creep_time_s"]) < 0.011


def test_the_simulation_block_adds_the_simulation_database_s_messages() -> None:
    """The page's [simulation] table names every message of the simulation database, each on its own 11-bit ID,
    and its [lockstep] table has the shipped binding's keys with the tick on SIM_SYNC's signal."""
    from dsg_hil.protocol import load_dbc
    from dsg_hil.protocol.binding import DEFAULT_BINDING

    (block,) = [b for b in blocks("docs/how-to/binding.md", "toml") if b.startswith("[simulation]")]
    shown = tomllib.loads(block)
    sim = load_dbc(ROOT / "dbc" / "dsg_hil_sim.dbc")
    ids = shown["simulation"]["ids"]
    assert set(ids) == {m.name for m in sim.messages}
    assert len(set(ids.values())) == len(ids) and all(0 <= i < 0x800 for i in ids.values())
    shipped = tomllib.loads(DEFAULT_BINDING.read_text(encoding="utf-8"))
    assert set(shown["lockstep"]) == set(shipped["lockstep"])
    message, signal_name = shown["lockstep"]["tick"].split(".")
    assert signal_name in {s.name for s in sim.get_message_by_name(message).signals}


def test_the_example_matrix_passes_the_binding_check() -> None:
    """The binding guide's check of the CAN FD example, from the checkout's root as the page's paths are: exit 0,
    each CAN FD message shown with its frame."""
    (line,) = sh_block("docs/how-to/binding.md", "dsg-hil binding check dbc/examples/")
    done = run(line, ROOT)
    assert done.returncode == 0, done.stderr
    assert "FD(" in done.stdout and done.stdout.splitlines()[0].startswith("quantity")


# -- connect your ECU ------------------------------------------------------------------------------------------

ECU_PAGE = "docs/tutorials/connect-ecu.md"
ECU_EXAMPLE = ROOT / "dbc" / "examples" / "arxml"


def ecu_words(tmp_path: Path) -> dict[str, str]:
    """The page's database for the example's (absolute), and the example's binding copied in as my_ecu's."""
    (tmp_path / "my_ecu.binding.toml").write_bytes((ECU_EXAMPLE / "tcu.binding.toml").read_bytes())
    return {"dbc/examples/arxml/tcu.arxml": str(ECU_EXAMPLE / "tcu.arxml")}


@pytest.mark.slow
def test_the_ecu_tutorial_s_skeleton_and_check_run(tmp_path: Path) -> None:
    """binding init writes the skeleton whose lines the page shows; binding check on the example's binding prints
    the page's table and last line; without T_CL_pred it exits 2 with the page's line."""
    words = ecu_words(tmp_path)
    (line,) = sh_block(ECU_PAGE, "dsg-hil binding init")
    command, _, target = line.partition(" > ")
    (tmp_path / "my_ecu.binding.toml").unlink()
    done = run(command, tmp_path, words)
    assert done.returncode == 0, done.stderr
    (tmp_path / target.strip()).write_text(done.stdout, encoding="utf-8")
    (shown,) = [b for b in blocks(ECU_PAGE, "text") if b.startswith("# P_CL_cmd")]
    check_shown(shown, done.stdout)
    words = ecu_words(tmp_path)
    (line,) = sh_block(ECU_PAGE, "dsg-hil binding check")
    done = run(line, tmp_path, words)
    assert done.returncode == 0, done.stderr
    (shown,) = [b for b in blocks(ECU_PAGE, "text") if b.startswith("quantity")]
    check_shown(shown, done.stdout)
    binding = tmp_path / "my_ecu.binding.toml"
    binding.write_text("".join(row for row in binding.read_text(encoding="utf-8").splitlines(keepends=True)
                               if not row.startswith("T_CL_pred")), encoding="utf-8")
    done = run(line, tmp_path, words)
    (shown,) = [b for b in blocks(ECU_PAGE, "text") if b.startswith("error:")]
    assert done.returncode == 2 and done.stderr.strip() == shown.strip() and done.stdout == ""


def test_the_ecu_tutorial_s_binding_is_the_example_s() -> None:
    """The page's binding is the example's, shortened: each of its lines is one of the file's, and it is TOML."""
    (block,) = [b for b in blocks(ECU_PAGE, "toml") if b.startswith("send = [")]
    tomllib.loads(block)
    rows = (ECU_EXAMPLE / "tcu.binding.toml").read_text(encoding="utf-8").splitlines()
    assert [row for row in block.splitlines() if row and row not in rows] == []


def test_the_ecu_tutorial_s_protection_tables_are_the_arxml_s() -> None:
    """The page's DBC tables give the protection the ARXML gives those messages (layout, data ID, length)."""
    from dsg_hil.protocol import load_dbc
    from dsg_hil.protocol.profiles import protection_for

    (block,) = [b for b in blocks(ECU_PAGE, "toml") if b.startswith("[messages.TCU_CMD]")]
    tables = tomllib.loads(block)["messages"]
    db = load_dbc(ECU_EXAMPLE / "tcu.arxml")
    assert len(tables) == 2
    for name, table in tables.items():
        message = db.get_message_by_name(name)
        assert protection_for(message, table["protection"]) == protection_for(message), name


@pytest.mark.slow
def test_the_ecu_tutorial_s_runs_and_rejects(tmp_path: Path) -> None:
    """The lock-step run on the example's pair: every frame taken. The run with the CRC fault, then the page's
    Python on its summary: it prints the page's line (the TCU_CMD frames rejected for their CRC)."""
    words = ecu_words(tmp_path)
    lines = [b for b in blocks(ECU_PAGE, "sh") if b.startswith("dsg-hil run --dbc")]
    assert len(lines) == 2 and "--fault" not in lines[0] and "--fault" in lines[1]
    done = run(lines[0].strip(), tmp_path, words)
    assert done.returncode == 0, done.stderr[-2000:]
    frames = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))["frames"]
    assert frames["rejected"] == 0 and frames["by_message"]["TCU_CMD"]["taken"] == 1000
    done = run(lines[1].strip(), tmp_path, words)
    assert done.returncode == 0, done.stderr[-2000:]
    (python,) = blocks(ECU_PAGE, "python")
    printed = subprocess.run([str(BIN / "python"), "-c", python], cwd=tmp_path, capture_output=True, text=True,
                             timeout=60, env=ENV)
    assert printed.returncode == 0, printed.stderr
    (shown,) = [b for b in blocks(ECU_PAGE, "text") if b.startswith("TCU_CMD")]
    assert printed.stdout == shown


def test_the_ecu_tutorial_s_vcan_lines_are_the_vcan_suite_s() -> None:
    """The vcan0 block (not run here) is the one dsg_hil/e2e/test_connect_ecu.py runs, line for line."""
    from dsg_hil.e2e import test_connect_ecu

    assert sh_block(ECU_PAGE, "ecu-stub -i socketcan") == [test_connect_ecu.ECU_LINE, test_connect_ecu.PLANT_LINE]


@pytest.mark.slow
def test_the_xcp_guide_s_commands_run(tmp_path: Path) -> None:
    """The first line serves XCP on the DBC's default IDs (on a fresh group and port; stopped once it says so); the
    A2L line writes the file. The third, on vcan0, is parsed by test_blocks.py."""
    from dsg_hil.protocol.bus import fresh_udp_group

    lines = sh_block("docs/how-to/xcp.md", "ecu-stub")
    group = fresh_udp_group()
    argv = [group["channel"] if w == "239.255.0.1" else w for w in shlex.split(lines[0], comments=True)]
    serving = subprocess.Popen([*argv, "--bus-kwargs", f"port={group['port']}"], cwd=tmp_path, stderr=subprocess.PIPE,
                               text=True, env=ENV)
    try:
        assert serving.stderr is not None
        said = [serving.stderr.readline() for _ in range(2)]
    finally:
        serving.send_signal(signal.SIGTERM)
        serving.communicate(timeout=60)
    assert "listening on udp_multicast" in said[0] and "XCP slave on CAN, master 0x7D0, slave 0x7D1" in said[1], said
    (a2l_line,) = [line for line in lines if "--a2l" in line]
    done = run(a2l_line, tmp_path)
    assert done.returncode == 0, done.stderr
    text = (tmp_path / "tcu.a2l").read_text(encoding="utf-8")
    assert "ASAP2_VERSION" in text and "/begin MEASUREMENT" in text


def test_the_layout_tree_is_the_checkout_s() -> None:
    """Every path the layout page's tree names is in the checkout, and every package folder of the checkout is
    named."""
    (tree,) = [b for b in re.findall(r"^```\n(.*?)^```", (ROOT / "docs/explanation/layout.md").read_text(
        encoding="utf-8"), re.S | re.M) if b.startswith("dbc/")]
    named = [line.split()[0] for line in tree.splitlines() if line and not line.startswith(" ")]
    assert [path for path in named if not (ROOT / path).exists()] == []
    packages = {f"{p.parent.relative_to(ROOT)}/" for p in ROOT.glob("dsg_hil/*/__init__.py")}
    assert packages - set(named) == set()



EXAMPLE_README = "dbc/examples/dct_fd/README.md"


@pytest.mark.slow
def test_the_example_readme_s_run_and_plot(tmp_path: Path) -> None:
    """The dct_fd README's first block as written, from the repository's root: the pair passes the check, the 40-s
    creep runs on it (ecu-stub in the process, on dct_fd), nothing rejected, CL then CH, CL engaged 50 ms later
    than on the shipped pair (the README says so); the plot of its .blf log is written."""
    lines = sh_block(EXAMPLE_README, "dsg-hil binding check")
    assert [line.split()[1] for line in lines] == ["binding", "run", "plot"]
    replace = {name: str(tmp_path / name) for name in ("creep.blf", "summary.json", "creep.png")}
    for line in lines:
        if line.split()[1] == "plot":
            pytest.importorskip("matplotlib", reason="the plots extra is not installed")
        done = run(line, ROOT, replace)
        assert done.returncode == 0, (line, done.stderr[-2000:])
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    assert summary["frames"]["rejected"] == summary["frames"]["unanswered_ticks"] == 0
    assert summary["frames"]["by_message"]["TCU_Demand"]["taken"] > 3900
    assert [p["clutch"] for p in summary["phases"]] == ["CL", "CH"]
    shipped = run("dsg-hil run --duration 40 --summary shipped.json", tmp_path)
    assert shipped.returncode == 0, shipped.stderr[-2000:]
    ours = json.loads((tmp_path / "shipped.json").read_text(encoding="utf-8"))
    assert summary["phases"][0]["start_s"] - ours["phases"][0]["start_s"] == pytest.approx(0.05, abs=1e-9)
    assert (tmp_path / "creep.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_the_example_readme_s_two_processes(tmp_path: Path) -> None:
    """The README's two-process block on a fresh udp_multicast group and port: ecu-stub in the background on dct_fd,
    the plant's lock-step run against it, nothing rejected at either end."""
    from dsg_hil.protocol.bus import fresh_udp_group

    lines = sh_block(EXAMPLE_README, "ecu-stub -i udp_multicast")
    fresh = fresh_udp_group()
    group, port = fresh["channel"], f"port={fresh['port']}"
    summary = tmp_path / "summary.json"

    def words(line: str) -> list[str]:
        found = [group if w == "239.255.12.34" else str(summary) if w == "summary.json" else w
                 for w in shlex.split(line.rstrip("& "), comments=True)]
        return [*found, "--bus-kwargs", port]

    tcu = subprocess.Popen([*words(lines[0]), "--idle-exit", "10"], cwd=ROOT, stdout=subprocess.DEVNULL,
                           stderr=subprocess.PIPE, text=True, env=ENV)
    try:
        plant = subprocess.run(words(lines[1]), cwd=ROOT, capture_output=True, text=True, timeout=600, env=ENV)
    finally:
        tcu.send_signal(signal.SIGTERM)
        tcu_err = tcu.communicate(timeout=60)[1]
    assert plant.returncode == 0, plant.stderr[-2000:]
    assert "rejected 0" in tcu_err, tcu_err
    result = json.loads(summary.read_text(encoding="utf-8"))
    assert result["frames"]["rejected"] == result["frames"]["unanswered_ticks"] == 0
    assert [p["clutch"] for p in result["phases"]] == ["CL"]


@pytest.mark.slow
def test_the_arxml_readme_s_check_and_run(tmp_path: Path) -> None:
    """The ARXML example's README block as written, from the repository's root: the pair passes the check, and the
    10-s creep on it (ecu-stub in the process, its E2E profiles and data IDs from the ARXML) rejects nothing and
    engages CL as on the shipped pair."""
    lines = sh_block("dbc/examples/arxml/README.md", "dsg-hil binding check")
    assert [line.split()[1] for line in lines] == ["binding", "run"]
    for line in lines:
        done = run(f"{line} --summary {tmp_path / 'summary.json'}" if " run " in line else line, ROOT)
        assert done.returncode == 0, (line, done.stderr[-2000:])
    summary = json.loads((tmp_path / "summary.json").read_text(encoding="utf-8"))
    assert summary["frames"]["rejected"] == summary["frames"]["unanswered_ticks"] == 0
    assert [p["clutch"] for p in summary["phases"]] == ["CL"]


@pytest.mark.slow
def test_the_sweep_tutorial_s_sweep_runs_and_ends_as_the_page_says(tmp_path: Path) -> None:
    """The tutorial's eight-run sweep as written (its results directory in a temporary one): it ends with the
    verdict the page quotes, and writes the page it names."""
    pytest.importorskip("distributed", reason="the sweep extra is not installed")
    (line,) = sh_block("docs/tutorials/sweep.md", "dsg-hil sweep dsg_hil/data/sweeps/safety.toml --n 8")
    quoted = re.search(r"It ended `(verdict: [^`]+)`", (ROOT / "docs/tutorials/sweep.md").read_text(encoding="utf-8"))
    assert quoted is not None
    words = shlex.split(line, comments=True)
    assert words[words.index("--out") + 1] == "sweep"
    words[words.index("--out") + 1] = str(tmp_path / "sweep")
    done = subprocess.run(words, cwd=ROOT, capture_output=True, text=True, timeout=1200, env=ENV)
    assert done.returncode == 0, done.stderr[-2000:]
    assert quoted.group(1) in done.stdout + done.stderr
    assert (tmp_path / "sweep" / "sweep.md").is_file()


@pytest.mark.slow
def test_the_paper_tutorial_s_two_reports_run(tmp_path: Path) -> None:
    """The tutorial's two report commands as written, in a temporary directory: the whole report, then the creep
    part from a recorded log (the first report's own, for the page's ecu.asc); each writes its report.md and says
    how the numbers compare with the paper."""
    pytest.importorskip("matplotlib", reason="the plots extra is not installed")
    first, second = sh_block("docs/tutorials/paper.md", "dsg-hil report --out report/")
    done = run(first, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert "paper vs dsg-hil: Section V.B:" in done.stdout + done.stderr
    assert (tmp_path / "report" / "report.md").is_file() and (tmp_path / "report" / "creep.log").is_file()
    done = run(second, tmp_path, {"ecu.asc": str(tmp_path / "report" / "creep.log")})
    assert done.returncode == 0, done.stderr[-2000:]
    assert (tmp_path / "other" / "report.md").is_file()
