"""Break31: a killed run's build directories are removed, a user's of a look-alike name never.

`stale_temporaries` matched build directories by name alone (``.report-build-<8 characters>``),
so a user's ``.report-build-mydrafts`` holding a thesis was removed with its content by the
next `design`/`run`, or by an interrupted command; only a directory the tool made (its marker
inside) or an empty one is removed now.
"""

from __future__ import annotations

from pathlib import Path

from tanksynth.artefacts.atomic import remove_stale, stale_temporaries
from tanksynth.artefacts.io import remove_interrupted_writes


def test_a_users_directory_of_a_build_name_is_kept(tmp_path: Path):
    for name in (".report-build-mydrafts", ".law-build-abcdefgh.tmp"):
        user = tmp_path / name
        user.mkdir()
        (user / "thesis.tex").write_text("months of work")
    remove_interrupted_writes(tmp_path)
    remove_stale(stale_temporaries(tmp_path))
    assert (tmp_path / ".report-build-mydrafts" / "thesis.tex").read_text() == "months of work"
    assert (tmp_path / ".law-build-abcdefgh.tmp" / "thesis.tex").is_file()


def test_a_killed_builds_directory_is_removed(tmp_path: Path):
    import tanksynth.artefacts.atomic as atomic

    made = atomic.build_directory(tmp_path, ".report-build-")
    (made / "report.tex").write_text("partial")
    empty = tmp_path / ".report-build-zzzzzzzz"
    empty.mkdir()
    removed = remove_interrupted_writes(tmp_path)
    assert made in removed and empty in removed
    assert not made.exists() and not empty.exists()
