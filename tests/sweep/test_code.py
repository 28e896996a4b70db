"""Which code made a sweep's runs (dsg_hil/sweep/code.py): the digest follows every source and data file and
nothing else, and a sweep whose runs come from other code than the install says so."""

from __future__ import annotations

import re

from dsg_hil.sweep.code import code_counts, code_digest, code_note, digest_of


def _package(root, files):
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root


def test_the_digest_follows_sources_and_data_and_nothing_else(tmp_path):
    files = {"__init__.py": "", "plant.py": "K = 1.0\n", "data/params.toml": "m = 1\n", "data/x.dbc": "BO_\n"}
    a = _package(tmp_path / "a" / "pkg", files)
    b = _package(tmp_path / "b" / "pkg", files)
    assert digest_of([a]) == digest_of([b]) and re.fullmatch(r"[0-9a-f]{12}", digest_of([a]))
    _package(b, {"__pycache__/plant.cpython-311.pyc": "bytes", "notes.txt": "not code"})
    assert digest_of([b]) == digest_of([a])  # compiled caches and other files do not count
    for name, text in (("plant.py", "K = 1.5\n"), ("data/params.toml", "m = 2\n"), ("data/x.dbc", "BO_ 1\n")):
        c = _package(tmp_path / f"c{len(name)}" / "pkg", {**files, name: text})
        assert digest_of([c]) != digest_of([a]), name
    moved = _package(tmp_path / "d" / "pkg", {**{k: v for k, v in files.items() if k != "plant.py"},
                                              "physics.py": files["plant.py"]})
    assert digest_of([moved]) != digest_of([a])  # a file's path counts, not only its bytes


def test_this_install_has_one_digest():
    assert code_digest() == code_digest() and re.fullmatch(r"[0-9a-f]{12}", code_digest())


def test_runs_of_other_code_are_named_and_counted():
    here = code_digest()
    assert code_note([{"code": here}] * 3, here) is None
    rows = [{"code": here}] * 2 + [{"code": "0123456789ab"}] * 5 + [{}]
    assert code_counts(rows) == {here: 2, "0123456789ab": 5, "unknown": 1}
    note = code_note(rows, here)
    assert note is not None and f"other code than this install ({here})" in note
    assert f"5 by 0123456789ab, 2 by {here}, 1 by unknown" in note
