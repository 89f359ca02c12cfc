"""What a page shows when a background job ends in an error: the job queue's own public
message (a full queue, a job that died), never a traceback or a server path, and an
incident id for anything unexpected."""

from __future__ import annotations

from dash.exceptions import BackgroundCallbackError

from pages._background import job_error_text


def test_the_queues_message_is_shown_as_it_is():
    exc = BackgroundCallbackError("An error occurred inside a background callback: the server's queue is full "
                                  "(64 jobs wait); try again later\n")
    assert job_error_text(exc) == "the server's queue is full (64 jobs wait); try again later"


def test_paths_and_further_lines_are_dropped():
    exc = BackgroundCallbackError("An error occurred inside a background callback: could not open "
                                  "/srv/secret/cache/x.db\nTraceback (most recent call last): ...")
    text = job_error_text(exc)
    assert "/srv/" not in text and "Traceback" not in text and "x.db" in text


def test_anything_else_gets_an_incident_id():
    text = job_error_text(KeyError("/srv/secret"))
    assert text.startswith("unexpected error (incident ") and "/srv/" not in text
