"""Hostile input against the dashboard: the links and the upload of the hardening issue,
timed from outside.

Part 1 starts a real server (``python app.py`` on loopback, its own empty cache folder)
and opens each link as a browser does (page HTML, app layout, the page's layout callback),
then posts a crafted job request straight to ``/_dash-update-component`` and sends a
foreign Host header. Printed per request: HTTP status, wall time [s], whether the answer
holds "Traceback".

Part 2 hands the Discrepancy page a zip of a few kB whose Parquet file claims 5 million
rows (200 MB as float64 arrays) and prints the answer's first words, the wall time [s],
the peak of Python allocations and the growth of this process's RSS [MB].

    python bench/bench_hostile.py
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.hardening.dashclient import DashSession  # noqa: E402
from tests.hardening.loadrun import start_server, stop_server  # noqa: E402

LINKS = (
    "/explorer?solver.time_step=1e-8&duration=20",
    "/maps?speeds=300:6000:14.3&torques=-500:1000:0.01501",
    "/colourmap?speeds=" + ",".join(["300:6000:0.05701"] * 40),
    "/pulsation?pressure=abc",
    "/studies?study=../../x",
    "/discrepancy?upload=../../etc",
)


def links() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        proc, base = start_server(Path(tmp) / "cache")
        try:
            s = DashSession(base)
            print(f"{'request':<60} {'status':>6} {'wall s':>7} traceback")
            for link in LINKS:
                t0 = time.perf_counter()
                r = s.open(link)  # HTML, layout and the page's layout callback
                print(f"{link[:60]:<60} {r.status:>6} {time.perf_counter() - t0:>7.3f} {'Traceback' in r.text}")
            s.open("/colourmap?speeds=1000,1100")
            crafted = {"state": {"speeds": "300:6000:0.001", "duration": 1e9}, "nonce": "x"}
            r, _ = s.run_background("colourmap-done.data", {"colourmap-job.data": crafted})
            print(f"{'crafted job (duration 1e9, no ticket)':<60} {r.status:>6} {r.seconds:>7.3f} "
                  f"{'Traceback' in r.text}  {r.text[60:130]}")
            r = DashSession(base, host_header="evil.example").request("/explorer")
            print(f"{'Host: evil.example':<60} {r.status:>6} {r.seconds:>7.3f} {'Traceback' in r.text}")
        finally:
            stop_server(proc)


def upload() -> None:
    import os

    os.environ["DAMPERSIM_CACHE_DIR"] = tempfile.mkdtemp()
    import app  # noqa: F401  (registers the pages)
    from tests.hardening.test_uploads import D, HEADER, data_url, hostile_parquet, measured, zip_bytes

    zipped = zip_bytes({"c/manifest.csv": HEADER + "a,torsional,1500,200,points/a.parquet,5000\n",
                        "c/points/a.parquet": hostile_parquet()})
    contents = data_url(zipped)
    D.upload(data_url(zip_bytes({"x/readme.txt": "warm-up"})), "warm.zip", [])  # imports and first store open
    out, took, peak, rss = measured(lambda: D.upload(contents, "hostile.zip", []))
    words = "refused" if "refused" in str(out[2]) else "accepted"
    print(f"zip of {len(zipped)} bytes, 5 000 000 rows: {words}; {took:.3f} s, Python peak {peak / 2**20:.1f} MB, "
          f"RSS +{rss / 2**20:.1f} MB")


if __name__ == "__main__":
    links()
    upload()
