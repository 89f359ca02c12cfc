"""Fixtures of the dashboard tier."""

from multiprocessing import forkserver

import pytest


@pytest.fixture
def jobs_here(cache_dir):
    """Job processes of this test use its cache folder. They are forked by a fork server,
    which keeps the environment it started with (the first job of the test session, maybe
    under another test's cache folder): it is stopped before and after the test, and the
    next job starts a new one."""
    forkserver._forkserver._stop()
    yield cache_dir
    forkserver._forkserver._stop()
