"""Every fenced block of the user docs (README.md, CONTRACT.md where there is one, docs/**/*.md) is accounted for:
run by a named test (its printed output, where a page shows it, checked by a named test), or marked as a kind that
is not run, with the reason. A new block that is neither fails here with its page and line; an entry that matches no
block any more (the page changed) fails too. Skipped without a checkout."""

from __future__ import annotations

import ast
import re
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(not (ROOT / "mkdocs.yml").exists(), reason="the docs are in the checkout only")


@dataclass(frozen=True)
class Block:
    """A fenced block: where it starts (the fence's line, 1-based), its language and its text."""

    page: str
    line: int
    language: str
    text: str


FENCE = re.compile(r"^(\s*)(`{3,}|~{3,})\s*([\w+-]*)")


def fenced_blocks(path: Path) -> list[Block]:
    """The fenced blocks of one Markdown page (CommonMark: a fence closes on a line of at least its own run)."""
    lines = path.read_text(encoding="utf-8").splitlines()
    found, i = [], 0
    while i < len(lines):
        opened = FENCE.match(lines[i])
        if not opened:
            i += 1
            continue
        fence, j = opened.group(2), i + 1
        while j < len(lines) and not lines[j].strip().startswith(fence):
            j += 1
        found.append(Block(str(path.relative_to(ROOT)), i + 1, opened.group(3), "\n".join(lines[i + 1:j])))
        i = j + 1
    return found


def pages() -> list[Path]:
    """The user docs: the landing page, the contract, the site's pages, the example matrices' READMEs."""
    return [p for p in (ROOT / "README.md", ROOT / "CONTRACT.md") if p.exists()] \
        + sorted((ROOT / "docs").rglob("*.md")) + sorted((ROOT / "dbc" / "examples").rglob("README.md"))


# What a block is. RUN: a test runs it as shown (the entry says what it replaces: a fresh port, a file). Not run, each
# with its reason: OUTPUT (what a command printed: the test named compares it), EXCERPT (part of a shipped file or the
# checkout, the test named compares it), VCAN (needs vcan0: the VM suite runs it, dsg-hil vcan), PARSED (the user's
# own files, hosts or hardware, or minutes of runs: test_blocks.py parses each command line with the command's own
# parser), STUDY (a bench/ study of minutes to hours: the test named runs the script on a few short runs), INSTALL
# (installs packages: CI installs as README.md says), DIAGRAM, CITATION, FORMULA.
RUN, OUTPUT, EXCERPT, VCAN = "run", "output", "excerpt", "vcan"
PARSED, STUDY, INSTALL, DIAGRAM, CITATION, FORMULA = "parsed", "study", "install", "diagram", "citation", "formula"
NEEDS_A_TEST = {RUN, OUTPUT, EXCERPT, VCAN, STUDY}
NOT_RUN = {OUTPUT, EXCERPT, VCAN, PARSED, STUDY, INSTALL, DIAGRAM, CITATION, FORMULA}
PARSE_TEST = "tests/docs/test_blocks.py::test_every_documented_command_line_parses"
QUICK_START = "tests/docs/test_blocks.py::test_the_quick_start_run_prints_what_the_readme_shows"
GUIDES = "tests/docs/test_guides.py"
ECU = "docs/tutorials/connect-ecu.md"
ECU_CHECK, ECU_RUNS = (f"{GUIDES}::test_the_ecu_tutorial_s_skeleton_and_check_run",
                       f"{GUIDES}::test_the_ecu_tutorial_s_runs_and_rejects")


@dataclass(frozen=True)
class Entry:
    """One block, by its page and the start of its text; how it is covered."""

    page: str
    start: str
    kind: str
    by: tuple[str, ...] = ()  # "path" or "path::function" (a test, or the fixture that runs the command)
    why: str = ""


E = Entry
ENTRIES = [
    # README.md
    E("README.md", "pip install . && dsg-hil run\n", RUN, (QUICK_START, ".ci/run"),
      "CI runs both commands as written; the test runs the run and compares its lines"),
    E("README.md", "run: creep on grade", OUTPUT, (QUICK_START,)),
    E("README.md", "pip install '.[docs]' && mkdocs build --strict", RUN, ("tests/docs/test_site.py::site",)),
    E("README.md", "pip install -e '.[dev]' && ruff check .", RUN, (".ci/run",), "CI's third step, as written"),
    E("README.md", "@misc{", CITATION, why="a citation to copy"),
    # tutorials
    E("docs/tutorials/first-creep.md", "dsg-hil run --log run.log --summary summary.json", RUN, (QUICK_START,)),
    E("docs/tutorials/python.md", "from dsg_hil.sim.run import", RUN,
      ("tests/sim/test_run.py::test_the_tutorial_example_runs",)),
    E("docs/tutorials/pytest.md", '"""My controller', RUN,
      ("tests/testing/test_example.py::test_the_readme_example_passes",)),
    E("docs/tutorials/vcan.md", "sudo modprobe vcan", VCAN, ("dsg_hil/e2e/vcan.py",),
      "root and a kernel with vcan: dsg-hil vcan makes vcan0 so, natively or in its VM"),
    E("docs/tutorials/vcan.md", "dsg-hil run --interface socketcan --channel vcan0", VCAN,
      ("dsg_hil/e2e/test_end_to_end.py::test_the_tutorial_s_run_starts_the_tcu_as_a_process_on_vcan0",),
      "needs vcan0 (run with --duration)"),
    E("docs/tutorials/vcan.md", "dsg-hil plant --interface socketcan --channel vcan0", VCAN,
      ("dsg_hil/e2e/conftest.py::lockstep",), "needs vcan0: the suite's lock-step pair is this plant and ecu-stub"),
    E(ECU, "dsg-hil binding init dbc/examples/arxml/", RUN, (ECU_CHECK,), "the output redirected by the test"),
    E(ECU, "# P_CL_cmd (required)", OUTPUT, (ECU_CHECK,)),
    E(ECU, "send = [", EXCERPT, (f"{GUIDES}::test_the_ecu_tutorial_s_binding_is_the_example_s",)),
    E(ECU, "dsg-hil binding check dbc/examples/arxml/", RUN, (ECU_CHECK,), "the example's binding as my_ecu's"),
    E(ECU, "quantity           dir", OUTPUT, (ECU_CHECK,)),
    E(ECU, "error: my_ecu.binding.toml: quantities: T_CL_pred", OUTPUT, (ECU_CHECK,)),
    E(ECU, "[messages.TCU_CMD]", EXCERPT, (f"{GUIDES}::test_the_ecu_tutorial_s_protection_tables_are_the_arxml_s",)),
    E(ECU, "dsg-hil run --dbc dbc/examples/arxml/", RUN, (ECU_RUNS,), "the example's binding as my_ecu's"),
    E(ECU, "ecu-stub -i socketcan -c vcan0 --dbc dbc/examples/arxml/", VCAN,
      ("dsg_hil/e2e/test_connect_ecu.py::test_the_ecu_tutorial_s_pair_on_vcan0_in_real_time",
       f"{GUIDES}::test_the_ecu_tutorial_s_vcan_lines_are_the_vcan_suite_s"), "needs vcan0 (the suite's --duration)"),
    E(ECU, "dsg-hil plant -i socketcan -c can0 --dbc my_ecu.dbc", PARSED, why="the user's ECU, bus and files"),
    E(ECU, "import json", RUN, (ECU_RUNS,)),
    E(ECU, "TCU_CMD {'crc'", OUTPUT, (ECU_RUNS,)),
    E("docs/tutorials/sweep.md", "pip install 'dsg-hil[sweep]'", PARSED,
      why="an overview: an install, the user's spaces (SPACE.toml, SOBOL.toml), a cluster's address and 200-run "
          "sweeps; each line parsed, the sweeps themselves run at a smaller size by tests/sweep"),
    E("docs/tutorials/sweep.md", "dsg-hil sweep dsg_hil/data/sweeps/safety.toml --n 8", RUN,
      (f"{GUIDES}::test_the_sweep_tutorial_s_sweep_runs_and_ends_as_the_page_says",), "its --out in a temporary place"),
    E("docs/tutorials/paper.md", "dsg-hil report --out report/", RUN,
      (f"{GUIDES}::test_the_paper_tutorial_s_two_reports_run",), "the first report's log for the page's ecu.asc"),
    # how-to guides
    E("docs/how-to/install.md", "python3 -m venv .venv", INSTALL, (".ci/run",), "CI makes fresh environments so"),
    E("docs/how-to/install.md", "sudo apt-get install can-utils", INSTALL, why="system packages (root)"),
    E("docs/how-to/faults.md", "[[fault]]", EXCERPT,
      ("tests/docs/test_blocks.py::test_every_toml_block_of_fault_tables_is_a_fault_the_dbc_takes",)),
    E("docs/how-to/faults.md", "dsg-hil run --duration", RUN, (f"{GUIDES}::test_the_fault_guide_s_run_runs",),
      "the first line run; the other two on a real bus and vcan0 are parsed"),
    E("docs/how-to/faults.md", "from dsg_hil.protocol.faults import", RUN,
      ("tests/docs/test_blocks.py::test_the_fault_guide_s_python_block_gives_the_counts_it_shows",)),
    E("docs/how-to/binding.md", "send = [", EXCERPT, (f"{GUIDES}::test_the_binding_guide_s_file_is_a_binding",)),
    E("docs/how-to/binding.md", "dsg-hil binding check my_ecu.dbc", RUN,
      (f"{GUIDES}::test_the_binding_check_prints_the_guide_s_columns",), "the shipped DBC and binding for the user's"),
    E("docs/how-to/binding.md", "quantity           dir", OUTPUT,
      (f"{GUIDES}::test_the_binding_check_prints_the_guide_s_columns",)),
    E("docs/how-to/binding.md", "values         TCU", OUTPUT,
      (f"{GUIDES}::test_the_binding_check_prints_the_guide_s_values",)),
    E("docs/how-to/binding.md", "dsg-hil plant -i socketcan -c can0", PARSED, why="a real bus and the user's files"),
    E("docs/how-to/binding.md", "dsg-hil run --dbc my_ecu.dbc", RUN,
      (f"{GUIDES}::test_the_binding_guide_s_run_moves_both_ends",),
      "the first line with another matrix for the user's; the ecu-stub line on vcan0 is parsed"),
    E("docs/how-to/binding.md", "[simulation]", EXCERPT,
      (f"{GUIDES}::test_the_simulation_block_adds_the_simulation_database_s_messages",)),
    E("docs/how-to/binding.md", "dsg-hil binding check dbc/examples/dct_fd/", RUN,
      (f"{GUIDES}::test_the_example_matrix_passes_the_binding_check",)),
    # the example matrices
    E("dbc/examples/dct_fd/README.md", "dsg-hil binding check dbc/examples/dct_fd/", RUN,
      (f"{GUIDES}::test_the_example_readme_s_run_and_plot",)),
    E("dbc/examples/dct_fd/README.md", "ecu-stub -i udp_multicast", RUN,
      (f"{GUIDES}::test_the_example_readme_s_two_processes",), "on a fresh group and port"),
    E("dbc/examples/arxml/README.md", "dsg-hil binding check dbc/examples/arxml/", RUN,
      (f"{GUIDES}::test_the_arxml_readme_s_check_and_run",), "the run with --summary added, to check it"),
    E("dbc/examples/dct_fd/README.md", "sudo ip link set vcan0 mtu 72", VCAN,
      ("dsg_hil/e2e/test_second_matrix.py::test_plant_and_ecu_stub_on_the_second_matrix_over_vcan0",),
      "root and vcan0: the VM suite runs the two processes on vcan0 with this pair (dsg-hil vcan)"),
    E("docs/how-to/diag-command.md", "pip install 'dsg-hil[diag]'", INSTALL, why="an extra; the dev extra has it"),
    E("docs/how-to/diag-command.md", "ecu-stub -i udp_multicast -c 239.255.12.34", RUN,
      (f"{GUIDES}::test_the_diag_guide_s_session_prints_what_it_shows",), "on a fresh port"),
    E("docs/how-to/diag-command.md", "dsg-hil plant -i udp_multicast -c 239.255.12.34", RUN,
      (f"{GUIDES}::test_the_diag_guide_s_session_prints_what_it_shows",), "on a fresh port"),
    E("docs/how-to/diag-command.md", "DTC     name", OUTPUT,
      (f"{GUIDES}::test_the_diag_guide_s_session_prints_what_it_shows",)),
    E("docs/how-to/diag-command.md", "dsg-hil diag read state", RUN,
      (f"{GUIDES}::test_the_diag_guide_s_session_prints_what_it_shows",), "on a fresh port"),
    E("docs/how-to/diag-command.md", "0x0102  state", OUTPUT,
      (f"{GUIDES}::test_the_diag_guide_s_session_prints_what_it_shows",)),
    E("docs/how-to/diag-command.md", "dsg-hil diag clear", RUN,
      (f"{GUIDES}::test_the_diag_guide_s_session_prints_what_it_shows",), "on a fresh port"),
    E("docs/how-to/diag-command.md", "cleared DTC group", OUTPUT,
      (f"{GUIDES}::test_the_diag_guide_s_session_prints_what_it_shows",)),
    E("docs/how-to/diag-command.md", "request_id = 0x7E0", EXCERPT,
      (f"{GUIDES}::test_the_diag_guide_s_description_loads",)),
    E("docs/how-to/diag-command.md", "dsg-hil diag dtc --description my_ecu.toml", PARSED,
      why="the user's ECU on a real bus"),
    E("docs/how-to/diagnostics.md", '"""A lost PLANT_VEHICLE', RUN,
      ("tests/docs/test_diagnostics.py::test_the_guide_s_pytest_example_passes",)),
    E("docs/how-to/fmi.md", "import subprocess", RUN,
      ("tests/fmi/test_readme.py::test_the_guide_s_fmpy_snippet_runs",)),
    E("docs/how-to/xcp.md", "ecu-stub -i udp_multicast -c 239.255.0.1 --xcp", RUN,
      (f"{GUIDES}::test_the_xcp_guide_s_commands_run",), "lines 1-2 run (1 on a fresh port); 3 (vcan0) parsed"),
    E("docs/how-to/xcp.md", "import logging", RUN,
      ("tests/docs/test_xcp_guide.py::test_the_guide_s_script_prints_what_it_shows",)),
    E("docs/how-to/xcp.md", "connected to ecu_stub", OUTPUT,
      ("tests/docs/test_xcp_guide.py::test_the_guide_s_script_prints_what_it_shows",)),
    E("docs/how-to/interfaces.md", "dsg-hil run -i udp_multicast", RUN,
      (f"{GUIDES}::test_the_interfaces_guide_s_run_runs",)),
    E("docs/how-to/interfaces.md", "$ dsg-hil plant -i udp_multicast --mode lockstep", RUN,
      (f"{GUIDES}::test_the_interfaces_guide_s_two_sides_start_as_shown",),
      "the plant and the TCU as shown; can.viewer is a terminal UI: parsed only"),
    E("docs/how-to/logs.md", "dsg-hil run --log run.log\n", RUN, (QUICK_START,), "the quick start's run, with --log"),
    E("docs/how-to/parameters.md", "dsg-hil params --source calibrated", RUN,
      ("tests/docs/test_blocks.py::test_the_parameters_guide_runs",)),
    E("docs/how-to/parameters.md", "dsg-hil params --set vehicle.m=9000", RUN,
      ("tests/docs/test_blocks.py::test_the_parameters_guide_runs",)),
    E("docs/how-to/dask.md", "dsg-hil sweep SPACE.toml --scheduler", PARSED, why="the user's space and cluster"),
    E("docs/how-to/dask.md", "dsg-hil sweep SPACE.toml --out DIR --resume", PARSED,
      why="the user's space and an earlier sweep's folder (tests/sweep/test_resume_search.py resumes one)"),
    E("docs/how-to/run-tests.md", "pytest -n auto && dsg-hil vcan --install --load 2", RUN, (".ci/run",),
      "the README's second quick-start command, as CI runs it"),
    E("docs/how-to/run-tests.md", "dsg-hil vcan --load 4 -- python bench/vcan_timing.py", VCAN,
      ("bench/vcan_timing.py",),
      "a benchmark on vcan0 in the VM; its figures are not asserted"),
    # reference, explanation
    E("docs/reference/e2e.md", "# four messages' protections", EXCERPT,
      ("tests/protocol/test_profiles.py::test_the_pages_tables_are_specs_and_its_python_runs",)),
    E("docs/reference/e2e.md", "import can", RUN,
      ("tests/protocol/test_profiles.py::test_the_pages_tables_are_specs_and_its_python_runs",)),
    E("docs/explanation/layout.md", "dbc/dsg_hil.dbc ", EXCERPT,
      (f"{GUIDES}::test_the_layout_tree_is_the_checkout_s",)),
    E("docs/explanation/model.md", "mu = A", FORMULA, why="the paper's friction law (6) as printed"),
    E("docs/explanation/lockstep.md", "sequenceDiagram", DIAGRAM, why="Mermaid"),
    E("docs/index.md", "flowchart LR", DIAGRAM, why="Mermaid"),
    E("docs/index.md", "pip install . && dsg-hil run", RUN, (QUICK_START, ".ci/run"), "the README's quick start"),
    E("docs/safety.md", "B_c = T_pred,c", FORMULA, why="the thermal monitor's bound (ecu_stub/monitor.py)"),
    E("docs/safety.md", "T_pred ≥ T_safe", FORMULA, why="the hand-over limit (CreepController.limit)"),
    E("docs/safety.md", "f = P_REL", FORMULA, why="the heat's error (CreepController.heat_error_fraction)"),
    E("docs/safety.md", "e_c     = prediction_error_k", FORMULA, why="the margin's term (CreepController.margin_k)"),
    E("docs/safety.md", "dsg-hil run --summary s.json --fault 'offset:", PARSED,
      why="two default-scenario runs; tests/ecu_stub/test_sensor_checks.py runs such faults closed-loop"),
    E("docs/safety.md", "dsg-hil sweep dsg_hil/data/sweeps/safety.toml --n 1000", PARSED,
      why="1,000 creeps of 240 s each take hours; tests/sweep runs sweeps of the same engine on a few short runs"),
    E("docs/safety.md", "python bench/latent_findings.py --n 300", STUDY,
      ("tests/test_bench.py::test_latent_findings_counts_the_runs_by_their_latent_faults",),
      "a study of 300 runs, 20-40 minutes"),
    E("docs/safety.md", "sed 's/^seed = 1$/seed = 101/' dsg_hil/data/sweeps/safety.toml", STUDY,
      ("tests/test_bench.py::test_latent_findings_counts_the_runs_by_their_latent_faults",
       "tests/sweep/test_engines.py::test_the_benches_over_a_sweep_read_it_and_repeat_its_runs"),
      "the proof run: 10,000 runs and a 1,000-trial search, many hours on two cores"),
    E("docs/safety.md", "python bench/rerun_sweep_runs.py batch-105 r00954 --without-latent", STUDY,
      ("tests/test_bench.py::test_rerun_sweep_runs_replaces_the_latent_faults_only",),
      "a run of the proof's seed 105, whose folder the proof run writes"),
]


def matches(entry: Entry, block: Block) -> bool:
    return entry.page == block.page and (block.text + "\n").startswith(entry.start)


def all_blocks() -> list[Block]:
    return [block for page in pages() for block in fenced_blocks(page)]


def test_the_collector_finds_the_blocks_of_a_page(tmp_path):
    page = ROOT / "docs" / "how-to" / "parameters.md"
    found = fenced_blocks(page)
    assert [(b.language, b.text) for b in found[:1]] == [("sh", "dsg-hil params --source calibrated")]
    assert all(page.read_text(encoding="utf-8").splitlines()[b.line - 1].startswith("```") for b in found)


def test_every_block_is_run_or_marked_with_a_reason():
    missing, doubled = [], []
    for block in all_blocks():
        hits = [e for e in ENTRIES if matches(e, block)]
        if not hits:
            missing.append(f"{block.page}:{block.line} [{block.language}] {block.text.splitlines()[:1]}")
        elif len({(e.kind, e.by) for e in hits}) > 1:
            doubled.append(f"{block.page}:{block.line}")
    assert missing == [], "blocks no test runs and no entry marks (tests/docs/test_inventory.py ENTRIES)"
    assert doubled == []


def test_every_entry_names_a_block_and_a_kind_it_can_have():
    blocks = all_blocks()
    for entry in ENTRIES:
        assert any(matches(entry, b) for b in blocks), f"no block of {entry.page} starts {entry.start!r}"
        assert entry.kind in NEEDS_A_TEST | NOT_RUN, entry
        assert entry.by or entry.kind not in NEEDS_A_TEST, f"{entry}: which test?"
        assert entry.why or entry.kind in {RUN, OUTPUT, EXCERPT}, f"{entry}: why not run (or what is added)?"


def _defines(path: Path, name: str) -> bool:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    return any(isinstance(node, ast.FunctionDef) and node.name == name for node in ast.walk(tree))


def test_the_tests_named_exist():
    for entry in ENTRIES:
        for target in entry.by:
            path, _, name = target.partition("::")
            assert (ROOT / path).is_file(), f"{entry.page}: {path}"
            assert not name or _defines(ROOT / path, name), f"{entry.page}: {target}"


def test_a_parsed_command_line_is_parsed():
    """A block marked PARSED holds command lines that test_blocks.py parses (dsg-hil, ecu-stub, identify)."""
    from .test_blocks import LINES

    where = {w.split(": ", 1)[0] for w, _ in LINES}
    for entry in ENTRIES:
        if entry.kind == PARSED:
            assert entry.page in where, entry
