"""`replace_block`: a validation study's block goes between its markers, before the notes,
or at the end of its page."""

from __future__ import annotations

from pathlib import Path

from elastoflow.validation._report import replace_block

BEGIN, END = "<!-- x:begin -->", "<!-- x:end -->"


def test_a_block_replaces_its_old_self_or_goes_before_the_notes_or_last(tmp_path: Path) -> None:
    page = tmp_path / "page.md"
    page.write_text("# Title\n\nIntro.\n\n## Notes\n\n* a note\n")
    replace_block(page, f"{BEGIN}\nfirst\n{END}", BEGIN, END)
    assert page.read_text() == f"# Title\n\nIntro.\n\n{BEGIN}\nfirst\n{END}\n\n## Notes\n\n* a note\n"
    replace_block(page, f"{BEGIN}\nsecond\n{END}", BEGIN, END)
    assert page.read_text() == f"# Title\n\nIntro.\n\n{BEGIN}\nsecond\n{END}\n\n## Notes\n\n* a note\n"
    plain = tmp_path / "plain.md"
    plain.write_text("# Title\n\n\n")
    replace_block(plain, f"{BEGIN}\nonly\n{END}", BEGIN, END, before=None)
    assert plain.read_text() == f"# Title\n\n{BEGIN}\nonly\n{END}\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["page.md", "plain.md"]
