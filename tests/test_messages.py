"""Messages of the command line (tanksynth/messages.py): one line, within the limit."""

from __future__ import annotations

from tanksynth.messages import MAX_MESSAGE, design_index_note, one_line


def test_index_note_fits_the_line_with_the_message_cut():
    text = "key 'design[41].x': " + "y" * 700
    out = design_index_note(one_line(ValueError(text)))
    assert len(out) <= MAX_MESSAGE and "\n" not in out
    assert out.endswith("(design[41] = [[design]] table 42; indices count from 0)")
    assert " ... (cut)" in out


def test_no_index_no_note_and_long_digit_runs_shortened():
    assert design_index_note("plain") == "plain"
    assert one_line(ValueError("N = " + "9" * 50)) == "N = <50 digits>"
