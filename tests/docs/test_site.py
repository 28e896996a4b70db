"""The documentation site builds offline with warnings as errors (mkdocs build --strict): a broken link or anchor,
a page missing from the navigation, an API object mkdocstrings cannot find, or a reference page the hook cannot make
from the code fails it. Skipped without a checkout (an installed package has no docs/)."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(not (ROOT / "mkdocs.yml").exists(), reason="the docs are in the checkout only")


def hook() -> ModuleType:
    """The site's hook module (docs/ is no package: loaded from its file, as MkDocs does)."""
    spec = importlib.util.spec_from_file_location("docs_reference_hook", ROOT / "docs" / "hooks" / "reference.py")
    assert spec and spec.loader
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def site(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("site")
    done = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(out)], cwd=ROOT,
                          capture_output=True, text=True, timeout=600,
                          env={**os.environ, "NO_MKDOCS_2_WARNING": "1"})  # Material's notice, not a warning
    assert done.returncode == 0, done.stderr[-4000:]
    return out


@pytest.mark.slow
def test_every_command_and_option_is_on_the_cli_page(site):
    page = (site / "reference" / "cli" / "index.html").read_text(encoding="utf-8")
    for name, parser in hook().parsers().items():
        assert name in page, name
        for action in parser._actions:
            for option in action.option_strings:
                assert option in page, f"{name} {option}"


def test_every_dbc_signal_and_parameter_is_on_its_page(site):
    import tomllib

    import cantools

    dbc = (site / "reference" / "dbc" / "index.html").read_text(encoding="utf-8")
    for message in cantools.database.load_file(str(ROOT / "dbc" / "dsg_hil.dbc")).messages:
        assert f"0x{message.frame_id:03X}" in dbc and all(s.name in dbc for s in message.signals), message.name
    assert "End-to-end protection" in dbc and "CRC-8 SAE J1850" in dbc  # the protection module's own statement
    params = (site / "reference" / "params" / "index.html").read_text(encoding="utf-8")
    data = tomllib.loads((ROOT / "dsg_hil" / "data" / "params.toml").read_text(encoding="utf-8"))
    assert f"{data['vehicle']['m']['value']}" in params and "vehicle.m" in params


def test_the_codes_page_has_every_exit_code_and_fault_kind(site):
    from dsg_hil.common import errors
    from dsg_hil.protocol.faults import KINDS

    page = (site / "reference" / "codes" / "index.html").read_text(encoding="utf-8")
    for name, value in vars(errors).items():
        if name.startswith("EXIT_"):
            assert re.search(rf"<td>{value}</td>\s*<td><code>{name}</code>", page), name
    assert all(f"<code>{kind}</code>" in page for kind in KINDS)


def test_the_api_page_renders_the_docstrings(site):
    from dsg_hil.sim.run import RunConfig

    page = " ".join((site / "reference" / "api" / "index.html").read_text(encoding="utf-8").split())
    words = " ".join((RunConfig.__doc__ or "").split()[:3])  # its docstring's first words, rendered
    assert "open_run" in page and "dsg_hil_run" in page and "run_sweep" in page and words in page, words
    assert not re.search(r":(class|func|meth|mod|data):<code>", page)  # roles read as code


def test_the_bad_input_page_has_every_case_the_tests_run(site):
    """docs/bad-input.md's table is made from the tests' CASES: every command line, with what its error names."""
    import html

    from ..cli.test_bad_input import CASES

    page = html.unescape(re.sub(r"<[^>]+>", "", (site / "bad-input" / "index.html").read_text(encoding="utf-8")))
    for program, argv, _, _, needle in CASES:
        assert " ".join(argv[:3]) in page and needle in page, (program, argv)
    assert f"\n{len(CASES)}\n" in page  # the last row's number


FILE_METAVAR = re.compile(r"FILE|DIR|LOG|FMU|DBC|A2L|KERNEL")  # an option that reads or writes a file


def test_every_option_naming_a_file_has_a_bad_input_case():
    """The bad-input page cannot miss a new option's row: every option of every command line that takes a file
    (by its metavar) is in a case of CASES."""
    from ..cli.test_bad_input import CASES

    names = {"dsg-hil": "dsg-hil", "ecu-stub": "ecu-stub", "identify": "python -m ecu_stub.identify"}
    used = {(names[p] if p != "dsg-hil" else f"dsg-hil {argv[0]}", a.split("=")[0]) for p, argv, *_ in CASES
            for a in argv if a.startswith("-")}
    missing = [f"{name} {'/'.join(action.option_strings)}" for name, parser in hook().parsers().items()
               for action in parser._actions
               if action.option_strings and action.nargs != 0 and FILE_METAVAR.search(str(action.metavar or ""))
               and not any((name, option) in used for option in action.option_strings)]
    assert missing == []


def test_the_performance_page_shows_every_recorded_result(site):
    """Every bench/results/*.json on the page, with its date, machine and command."""
    import html
    import json

    page = html.unescape((site / "performance" / "index.html").read_text(encoding="utf-8"))
    found = sorted((ROOT / "bench" / "results").glob("*.json"))
    assert found
    for path in found:
        data = json.loads(path.read_text(encoding="utf-8"))
        assert all(data[key] in page for key in ("date", "machine", "command")), path.name
        assert f'id="{path.stem}"' in page.replace("_", "_"), path.name


def test_the_figures_of_a_bench_become_tables():
    made = hook().figures({"ratio": 2.1, "peak": {"a": 1, "b": 2}, "cases": [{"case": "x", "T": 1}, {"case": "y"}],
                           "by_name": {"n1": {"v": 3}}})
    text = "\n".join(made)
    assert "| ratio | 2.1 |" in text and "| peak.a | 1 |" in text and "| case | T |" in text
    assert "| y |  |" in text and "\n| name | v |\n" in text and "\n| n1 | 3 |" in text


def test_the_readme_s_links_reach_files_of_the_checkout():
    """README.md is read on the forge and the package index, outside the site: its relative links are files."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    links = [link for link in re.findall(r"\]\(([^)#]+)[^)]*\)", readme) if "://" not in link]
    assert len(links) >= 10
    assert [link for link in links if not (ROOT / link).is_file()] == []


INTERNAL = re.compile(r"\bissues? #?\d|\bitems? \d|\bCEO\b", re.IGNORECASE)  # the work's words


def test_no_page_names_an_issue_number():
    """What users read says what the program does, not which work item changed it."""
    pages = [ROOT / "README.md", *(ROOT / "docs").rglob("*.md")]
    named = [p for p in pages if INTERNAL.search(p.read_text(encoding="utf-8"))]
    assert [str(p.relative_to(ROOT)) for p in named] == []


def test_no_generated_page_names_an_issue_number(site):
    """Nor the pages made from the code (the CLI's help, the bench scripts' docstrings, the DBC's comments)."""
    named = [str(p.relative_to(site)) for p in site.rglob("*.html")
             if INTERNAL.search(re.sub(r"<[^>]+>", " ", p.read_text(encoding="utf-8")))]
    assert named == []


def test_lists_written_for_github_are_lists_on_the_site():
    """A list right after a paragraph gets its blank line, nested items four spaces; code blocks stay as they are."""
    fix = hook().nested_lists
    assert fix("Text:\n- a\n  - b\n  lazy\n- c") == "Text:\n\n- a\n    - b\n  lazy\n- c"
    assert fix("```\nx\n  - y\n```") == "```\nx\n  - y\n```"
    assert fix("- a\n\n- b") == "- a\n\n- b"


def test_sphinx_roles_in_docstrings_read_as_code():
    fix = hook().plain_roles
    assert fix(":class:<code>~dsg_hil.sim.scenario.Scenario</code>") == "<code>Scenario</code>"
    assert fix(":mod:<code>dsg_hil.protocol.local</code>") == "<code>dsg_hil.protocol.local</code>"


def test_the_readme_is_a_landing_page_with_the_fixed_commands():
    """At most 150 lines; Quick start's first sh block the two commands CI runs; the editable install only under
    Contributing, as its one command."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")

    def first_sh(section: str) -> list[str]:
        body = readme.split(f"\n## {section}\n", 1)[1].split("\n## ", 1)[0]
        return body.split("```sh\n", 1)[1].split("```", 1)[0].splitlines()

    assert len(readme.splitlines()) <= 150
    assert first_sh("Quick start") == ["pip install . && dsg-hil run",
                                       "pip install '.[dev]' && pytest -n auto && dsg-hil vcan --install --load 2"]
    assert first_sh("Contributing") == [
        "pip install -e '.[dev]' && ruff check . && mypy && pytest -m \"not slow or wheel\""]
    assert readme.count(" -e ") == 1
