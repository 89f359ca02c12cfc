"""Importing recordings into a campaign: long recordings cut into points, every format
round-trips a synthetic campaign, bad input stops the import and leaves nothing behind."""

import json
import os

import numpy as np
import pytest

from dampersim.cli import main
from dampersim.discrepancy.campaign import read_campaign
from dampersim.discrepancy.synth import synthesize
from dampersim.errors import InputError
from dampersim.parameters import at_thesis_segments
from dampersim.rigdata.examples import EXTENSIONS, WRITERS, long_recording_channels, point_channels, write_recording
from dampersim.rigdata import importer
from dampersim.rigdata.importer import import_campaign
from dampersim.signal import order_amplitudes

FORMATS = tuple(WRITERS)
#: The example run's program (duration [s], speed [rpm], torque [N m] or a ramp), and the
#: plateaus' time spans [s] in it; the 9-14 s plateau at 2000 rpm follows a speed step.
PROGRAM = ((4.0, 1000.0, 100.0), (5.0, 1500.0, 200.0), (5.0, 2000.0, 150.0),
           (8.0, 1200.0, (-200.0, 300.0)), (5.0, 1800.0, 250.0))


#: How long after a commanded step the example's measured signals stay in the old band [s].
LAG_S = 0.05


@pytest.fixture(scope="module")
def long_runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("long-runs")
    channels = long_recording_channels(PROGRAM)
    return {fmt: write_recording(folder / f"long_run_{fmt}{EXTENSIONS[fmt]}", channels, fmt) for fmt in FORMATS}


@pytest.mark.parametrize("fmt", FORMATS)
def test_long_recording_is_cut_into_its_plateaus_and_ramp(long_runs, fmt, tmp_path):
    out = tmp_path / "campaign"
    report = import_campaign([long_runs[fmt]], out)
    kinds = [(p["kind"], round(p["speed_rpm"], -1)) for p in report.points]
    assert kinds == [("torsional", 1000), ("torsional", 1500), ("torsional", 2000), ("ramp", 1200), ("torsional", 1800)]
    starts = np.cumsum([0.0] + [seg[0] for seg in PROGRAM])
    for p, (t0, t1) in zip(report.points, zip(starts[:-1], starts[1:])):
        # every window inside its programme segment; the measured speed and torque follow a
        # step with a lag (a 0.8-2 Hz second-order response), so a plateau is still within
        # its tolerance band for a few tens of ms after the next step is commanded
        assert t0 - 1e-9 <= p["start_s"] < p["end_s"] <= t1 + LAG_S, p
    camp = read_campaign(out)
    assert camp.problems == [] and len(camp.points) == 5 and len(camp.ramps) == 1
    meta = json.loads((out / "campaign.json").read_text())
    assert meta["source"]["files"] == [os.path.basename(long_runs[fmt])] and meta["source"]["format"] == [fmt]
    assert meta["mapping"][os.path.basename(long_runs[fmt])]["input_torque_nm"]["name"] == "Trq_In"
    assert not any(n.startswith(".") for n in os.listdir(tmp_path))  # no temporary folder left


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory):
    """A small synthetic campaign (two torsional points and a ramp) from the library."""
    folder = tmp_path_factory.mktemp("synthetic") / "campaign"
    # the thesis's 18/8 base (a 24/10 truth): the formats are what is tested, and it is cheaper
    # to synthesise than the default 48/16
    synthesize(folder, points=["map_900_150", "map_1500_150", "ramp_1500"], record=0.8, seed=4,
               base=at_thesis_segments())
    return read_campaign(folder)


@pytest.mark.parametrize("fmt", FORMATS)
def test_synthetic_campaign_round_trips_through_every_format(synthetic, fmt, tmp_path):
    src = tmp_path / "recordings"
    src.mkdir()
    rows = ["id,kind,source_file,start_s,end_s"]
    for p in synthetic.points:
        path = write_recording(src / f"{p.id}{EXTENSIONS[fmt]}", point_channels(p), fmt)
        rows.append(f"{p.id},{p.kind},{os.path.basename(path)},0,{float(p.time[-1]) + 0.5 / p.sample_rate_hz!r}")
    cuts = tmp_path / "cuts.csv"
    cuts.write_text("\n".join(rows) + "\n")
    import_campaign([src], tmp_path / "imported", cuts_path=cuts)
    back = {p.id: p for p in read_campaign(tmp_path / "imported", strict=True).points}
    assert sorted(back) == sorted(p.id for p in synthetic.points)
    for p in synthetic.points:
        q = back[p.id]
        assert q.kind == p.kind and q.time.size == p.time.size
        if p.kind == "ramp":
            # windup in degrees, float32 storage both ways: 1e-5 of the largest windup
            assert np.allclose(q.windup, p.windup, atol=1e-5 * np.max(np.abs(p.windup)))
            continue
        for a, b in ((p.input_torque, q.input_torque), (p.output_torque, q.output_torque)):
            amp_a = order_amplitudes(a, p.sample_rate_hz, p.speed)
            amp_b = order_amplitudes(b, q.sample_rate_hz, q.speed)
            strong = amp_a >= 0.02 * amp_a.max()  # orders that carry the signal, not its noise floor
            # 0.5 %: the criterion; what the round trip adds is float32 and kN m rounding
            assert np.allclose(amp_b[strong], amp_a[strong], rtol=0.005)


def test_bad_input_stops_with_exit_2_and_leaves_nothing(long_runs, tmp_path, capsys):
    out = tmp_path / "campaign"
    garbage = tmp_path / "noise.mf4"
    garbage.write_bytes(os.urandom(4096))
    assert main(["import", str(garbage), "--out", str(out)]) == 2
    assert "noise.mf4" in capsys.readouterr().err and not out.exists()
    occupied = tmp_path / "occupied"
    occupied.mkdir()
    (occupied / "x.txt").write_text("keep me")
    assert main(["import", long_runs["csv"], "--out", str(occupied)]) == 2
    assert "not an empty folder" in capsys.readouterr().err and (occupied / "x.txt").read_text() == "keep me"
    bad_map = tmp_path / "map.toml"
    bad_map.write_text('[channels.input_torque_nm]\nname = "No_Such_Channel"\n')
    assert main(["import", long_runs["csv"], "--out", str(out), "--map", str(bad_map)]) == 2
    assert "No_Such_Channel" in capsys.readouterr().err and not out.exists()
    assert sorted(os.listdir(tmp_path)) == ["map.toml", "noise.mf4", "occupied"]


def test_edited_cuts_are_imported_as_given(long_runs, tmp_path, capsys):
    first = tmp_path / "first"
    assert main(["import", long_runs["mdf4"], "--out", str(first), "--json"]) == 0
    report = json.loads(capsys.readouterr().out)
    manifest = (first / "manifest.csv").read_text().splitlines()
    header, rows = manifest[0], manifest[1:]
    # keep the first two points, shorten the second by a second
    cols = header.split(",")
    kept = [dict(zip(cols, r.split(","))) for r in rows[:2]]
    kept[1]["end_s"] = repr(float(kept[1]["end_s"]) - 1.0)
    edited = tmp_path / "edited.csv"
    edited.write_text(header + "\n" + "\n".join(",".join(r[c] for c in cols) for r in kept) + "\n")
    second = tmp_path / "second"
    assert main(["import", long_runs["mdf4"], "--out", str(second), "--cuts", str(edited)]) == 0
    camp = read_campaign(second, strict=True)
    assert [p.id for p in camp.points] == [r["id"] for r in kept]
    # the point spans the cut less what the channels do not all cover: at most one sample
    # interval of the 500 Hz speed group at the end and one of the 2 kHz torque group
    cut = report["points"][1]["end_s"] - 1.0 - report["points"][1]["start_s"]
    assert cut - (1 / 500 + 1 / 2000) - 1e-9 <= camp.points[1].duration <= cut
    with pytest.raises(InputError, match="start_s"):
        bad = tmp_path / "bad.csv"
        bad.write_text(header + "\n" + rows[0].replace(",0.0,", ",-1,") + "\n")
        import_campaign([long_runs["mdf4"]], tmp_path / "third", cuts_path=bad)


def test_cuts_with_a_repeated_or_unsafe_id_are_refused(long_runs, tmp_path):
    name = os.path.basename(long_runs["csv"])
    for rows, field in ((["p1,torsional,{n},0.5,3.5", "p1,torsional,{n},5.5,8.5"], "given twice"),
                        (["../x,torsional,{n},0.5,3.5"], "names the point's file")):
        cuts = tmp_path / "cuts.csv"
        cuts.write_text("id,kind,source_file,start_s,end_s\n" + "\n".join(r.format(n=name) for r in rows) + "\n")
        with pytest.raises(InputError, match=field):
            import_campaign([long_runs["csv"]], tmp_path / "out", cuts_path=cuts)
        assert not (tmp_path / "out").exists()


def test_long_recordings_are_cut_piece_by_piece_as_a_whole(long_runs, tmp_path, monkeypatch):
    # the segmentation traces of a long recording are read in pieces; with 3 s pieces the
    # 27 s example goes through that path and must give the cuts of the whole-trace path
    whole = import_campaign([long_runs["tdms"]], tmp_path / "whole")
    monkeypatch.setattr(importer, "SEGMENT_PIECE_S", 3.0)
    pieces = import_campaign([long_runs["tdms"]], tmp_path / "pieces")
    cut = lambda r: [(p["kind"], p["start_s"], p["end_s"]) for p in r.points]  # noqa: E731
    assert cut(pieces) == cut(whole)
