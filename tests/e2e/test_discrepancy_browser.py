"""End-to-end: the Discrepancy page's checks in headless Chromium against a real server
(its job queue and fork server): the validation report at page load, a refused zip and an
accepted one, each checked by a background job while the page says it is checking.
"""

from __future__ import annotations

import io
import zipfile

import numpy as np
import pytest

from dampersim.discrepancy.campaign import MeasuredPoint
from dampersim.discrepancy.campaign_write import write_campaign
from tests.e2e import test_browser as TB

pytestmark = pytest.mark.e2e

server, browser, page = TB.server, TB.browser, TB.page  # the fixtures of the browser tier
EXAMPLE = "hidden-effect-example"


def zip_of(files: dict) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as zf:
        for name, data in files.items():
            zf.writestr(name, data)
    return buf.getvalue()


def small_campaign(tmp_path) -> bytes:
    """Three torsional points of 0.6 s at 5 kHz as a campaign zip (about 100 kB)."""
    pts = []
    for i in range(3):
        rpm, rate = 1000.0 + 300 * i, 5000.0
        t = np.arange(int(0.6 * rate) + 1) / rate
        ripple = 50.0 * np.sin(2 * np.pi * 2 * rpm / 60.0 * t)
        pts.append(MeasuredPoint(id=f"p{i}", kind="torsional", speed_rpm=rpm, mean_torque_nm=200.0, sample_rate_hz=rate,
                                 time=t, input_torque=200.0 + ripple, output_torque=200.0 + 0.5 * ripple,
                                 input_speed_rpm=np.full(t.size, rpm), output_speed_rpm=np.full(t.size, rpm)))
    folder = tmp_path / "small"
    write_campaign(folder, pts, name="small", fmt="parquet")
    return zip_of({f"small/{p.relative_to(folder).as_posix()}": p.read_bytes()
                   for p in sorted(folder.rglob("*")) if p.is_file()})


def upload(page, name, data):
    page.set_input_files("#discrepancy-upload input[type=file]",
                         files=[{"name": name, "mimeType": "application/zip", "buffer": data}])


def test_uploads_are_checked_by_jobs_and_a_refusal_keeps_the_campaign(server, page, tmp_path):
    page.goto(server + "/discrepancy")
    # the validation report of the example comes from a job started at page load
    TB.wait_text(page, "#discrepancy-report", r"\d+ of \d+ test points valid", timeout=90_000)
    assert page.locator("#discrepancy-report-checking").is_hidden()

    upload(page, "readme.zip", zip_of({"readme.txt": b"no campaign here"}))
    page.wait_for_selector("#discrepancy-upload-checking", state="visible", timeout=30_000)  # says it is checking
    TB.wait_text(page, "#discrepancy-upload-notices", "holds no manifest.csv", timeout=60_000)
    text = page.locator("#discrepancy-upload-notices").inner_text()
    assert "readme.zip" in text and "accepted is" in text
    assert page.locator("#discrepancy-upload-checking").is_hidden()
    assert f"example: {EXAMPLE}" in page.locator("#discrepancy-campaign").inner_text()  # the campaign stays

    upload(page, "small.zip", small_campaign(tmp_path))
    TB.wait_text(page, "#discrepancy-upload-notices", "was unpacked", timeout=60_000)
    TB.wait_text(page, "#discrepancy-campaign", "uploaded: small", timeout=30_000)  # listed and selected
    TB.wait_text(page, "#discrepancy-report", "3 of 3 test points valid", timeout=60_000)
    assert page.locator("#discrepancy-upload-checking").is_hidden()
    assert page.locator("#discrepancy-upload input[type=file]").count() == 1
