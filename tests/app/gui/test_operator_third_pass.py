"""The operator's session, third pass: work is never dropped unasked, the state shown is the state held, where a
result ran is named, and messages are in the operator's words. (The start-up window: ``test_startup.py``.)"""

import shutil

import pytest

from app.gui.widgets.questions import answering

from .test_review import reconstruct


# ---------------------------------------------------------------------- opening another recording asks first
def test_opening_another_recording_during_a_run_asks_naming_it_and_keeping_it_says_so(qtbot, opened, recording,
                                                                                        tmp_path):
    review = opened
    other = tmp_path / "other.zarr"
    shutil.copytree(recording, other)
    review.form.set_method_name("diffusion")
    assert review.reconstruct() is not None and review.model.busy
    with answering(False) as asked:
        assert review.open_recording(other) is None
    assert [q.accept for q in asked] == ["Open other.zarr"]
    assert asked[0].text.startswith("Opening other.zarr now:\n\n• the reconstruction running stops; what it "
                                    "computed is lost")
    qtbot.waitUntil(lambda: not review.model.busy, timeout=30_000)
    assert review.session.path == recording and len(review.results) == 1  # the run went on and was kept


def test_opening_another_recording_with_a_result_not_exported_asks_and_then_shows_only_the_new_one(
        qtbot, opened, recording, tmp_path):
    review = opened
    other = tmp_path / "other.zarr"
    shutil.copytree(recording, other)
    reconstruct(qtbot, review, "diffusion")
    with answering(True) as asked:
        review.open_recording(other)
    assert "1 reconstruction not exported is lost: diffusion" in asked[0].text
    qtbot.waitUntil(lambda: review.session.path == other, timeout=10_000)
    assert review.results == [] and review.model.result_line.text == ""
    with answering() as asked:  # nothing to lose now: no question
        review.open_recording(recording)
    assert asked == []
    qtbot.waitUntil(lambda: review.session.path == recording, timeout=10_000)


def test_a_run_cancelled_by_opening_another_recording_leaves_no_cancelled_line_on_the_new_one(
        qtbot, opened, recording, tmp_path):
    review = opened
    other = tmp_path / "other.zarr"
    shutil.copytree(recording, other)
    review.form.set_method_name("motion-aware")
    review.reconstruct()
    with answering(True):
        review.open_recording(other)
    qtbot.waitUntil(lambda: review.session.path == other and not review.model.busy, timeout=30_000)
    qtbot.wait(50)
    assert "cancelled" not in review.result_label.text() and review.results == []


def test_a_refused_open_names_the_recording_still_open(qtbot, opened, recording, tmp_path):
    review = opened
    (tmp_path / "junk.zarr").mkdir()
    review.open_recording(tmp_path / "junk.zarr")
    qtbot.waitUntil(lambda: "cannot open" in review.path_label.text(), timeout=5000)
    text = review.path_label.text()
    assert f"{recording} (still open)" in text and "cannot open junk.zarr" in text
    assert review.session.path == recording and review.reconstruct_button.isEnabled()


# ---------------------------------------------------------------------- messages in words
@pytest.mark.parametrize("message, words, gone", [
    ("/d/x.zarr: not a readable Zarr store (GroupNotFoundError: No group found in store /d/x.zarr at path '')",
     "is not a recording", "GroupNotFoundError"),
    ("/d/cal.json: not valid JSON (Expecting value at line 1)", "not a file flexvox wrote", "Expecting value"),
])
def test_messages_for_programmers_become_words_naming_what_to_open_instead(message, words, gone):
    from app.gui.models.operator_words import in_gui_words

    text = in_gui_words(message)
    assert words in text and gone not in text and "open" in text, text
