"""The command line refuses an unencrypted Dask scheduler on another machine unless the
user says so with --allow-insecure-dask (anyone who reaches such a scheduler can run code
in its workers)."""

from __future__ import annotations

import pytest

from dampersim.cli import main


def test_remote_tcp_scheduler_is_refused_with_exit_2(cache_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DAMPERSIM_ALLOW_INSECURE_DASK", raising=False)
    code = main(["sweep", "--speeds", "1000", "--scheduler", "tcp://192.0.2.10:8786", "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2
    assert "tls://" in err and "192.0.2.10" in err
    assert "Traceback" not in err


def test_the_flag_accepts_it_explicitly(cache_dir, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("DAMPERSIM_ALLOW_INSECURE_DASK", raising=False)
    # 192.0.2.0/24 is reserved for documentation: nothing answers there, so the sweep
    # fails on the connection (exit 2 with its own message), not on the address check
    code = main(["sweep", "--speeds", "1000", "--scheduler", "tcp://192.0.2.10:8786", "--allow-insecure-dask",
                 "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2
    assert "cannot reach the Dask scheduler" in err, err
    assert "is refused" not in err, err
