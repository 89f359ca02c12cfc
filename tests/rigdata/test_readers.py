"""Rig file readers: every format round-trips through the example writers, is recognised by
content, reads time windows as slices of the whole channel, and rejects bad input with an
InputError naming the file.

Tolerances: values are compared exactly, because every writer stores the dtype it is
given (float64 as float64; the float32 channel ``Speed_Out`` as float32, which reads back
as exactly ``float64(float32 value)``) and CSV is written with 17 significant digits.
Time stamps are exact where the file stores them (MDF4 master channel, MAT time vectors,
CSV); TDMS waveforms and MAT sample rates store a start and an interval, and the reader
recomputes ``start + i * interval``, which differs from the writer's ``i / rate`` by float64
rounding: 1e-12 s absolute. Sample rates are compared to 1e-9 relative for the same reason.
"""

import hashlib
import os
import random
import zipfile

import numpy as np
import pytest

from dampersim.errors import InputError
from dampersim.rigdata import examples
from dampersim.rigdata.readers import ChannelInfo, open_recording, sniff_format

FORMATS = ("mdf4", "tdms", "mat5", "mat73", "csv")
TIME_EXACT = {"mdf4": True, "tdms": False, "mat5": True, "mat73": True, "csv": True}
RATES = {"Trq_In": 2000.0, "Torque_Output": 2000.0, "n_In": 500.0, "Speed_Out": 500.0}


@pytest.fixture(scope="module")
def channels():
    return examples.demo_channels(duration_s=0.5)


def _digest(path):
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()


def _write(tmp_path, channels, fmt, name="rec"):
    return examples.write_recording(tmp_path / f"{name}{examples.EXTENSIONS[fmt]}", channels, fmt)


def _partition(infos):
    groups = {}
    for c in infos:
        groups.setdefault(c.group, set()).add(c.name)
    return sorted(sorted(g) for g in groups.values())


def _check_round_trip(path, channels, time_exact, fmt=None):
    before = _digest(path)
    with open_recording(path) as rec:
        if fmt:
            assert rec.format == fmt
        assert rec.path == os.path.abspath(path)
        assert all(isinstance(c, ChannelInfo) for c in rec.channels)
        assert sorted(c.name for c in rec.channels) == sorted(channels)
        assert _partition(rec.channels) == [["Speed_Out", "n_In"], ["Torque_Output", "Trq_In"]]
        for info in rec.channels:
            t_in, x_in, unit = channels[info.name]
            assert info.unit == unit
            assert info.samples == len(t_in)
            assert info.rate_hz == pytest.approx(RATES[info.name], rel=1e-9)
            t, x = rec.read(info.name)
            assert t.dtype == np.float64 and x.dtype == np.float64
            np.testing.assert_array_equal(x, np.asarray(x_in, dtype=np.float64))
            if time_exact:
                np.testing.assert_array_equal(t, t_in)
            else:
                np.testing.assert_allclose(t, t_in, rtol=0, atol=1e-12)
    assert _digest(path) == before  # the source file is never modified


@pytest.mark.parametrize("fmt", FORMATS)
def test_round_trip_through_the_example_writers(tmp_path, channels, fmt):
    path = _write(tmp_path, channels, fmt)
    assert sniff_format(path) == fmt
    _check_round_trip(path, channels, TIME_EXACT[fmt], fmt)


@pytest.mark.parametrize("fmt", ("mat5", "mat73"))
@pytest.mark.parametrize("layout, channel_time", [("groups", "vector"), ("channels", "vector"), ("channels", "rate")])
def test_mat_layouts(tmp_path, channels, fmt, layout, channel_time):
    writer = examples.write_mat5 if fmt == "mat5" else examples.write_mat73
    path = writer(tmp_path / "layout.mat", channels, layout=layout, channel_time=channel_time)
    with open_recording(path) as rec:
        if layout == "channels":  # one struct per channel: each its own time-base group
            assert sorted(c.group for c in rec.channels) == sorted(channels)
            rec.channels = tuple(ChannelInfo(c.name, c.unit, str(RATES[c.name]), c.samples, c.rate_hz)
                                 for c in rec.channels)
            assert _partition(rec.channels) == [["Speed_Out", "n_In"], ["Torque_Output", "Trq_In"]]
        for info in rec.channels:
            t, x = rec.read(info.name)
            assert info.unit == channels[info.name][2]
            assert info.rate_hz == pytest.approx(RATES[info.name], rel=1e-9)
            np.testing.assert_allclose(t, channels[info.name][0], rtol=0, atol=0 if channel_time == "vector" else 1e-12)
            np.testing.assert_array_equal(x, np.asarray(channels[info.name][1], dtype=np.float64))


@pytest.mark.parametrize("fmt", ("mat5", "mat73"))
def test_mat_flat_layout(tmp_path, channels, fmt):
    fast = {k: channels[k] for k in ("Trq_In", "Torque_Output")}
    writer = examples.write_mat5 if fmt == "mat5" else examples.write_mat73
    with open_recording(writer(tmp_path / "flat.mat", fast, layout="flat")) as rec:
        assert [(c.name, c.unit, c.group) for c in rec.channels] == [("Trq_In", "kN m", "time"),
                                                                    ("Torque_Output", "N m", "time")]
        np.testing.assert_array_equal(rec.read("Trq_In")[1], fast["Trq_In"][1])
    with pytest.raises(InputError, match="flat"):
        writer(tmp_path / "two.mat", channels, layout="flat")


def test_tdms_time_channel_layout(tmp_path, channels):
    path = examples.write_tdms(tmp_path / "timechan.tdms", channels, time_channel=True)
    _check_round_trip(path, channels, time_exact=True)


def test_csv_units_row_semicolon(tmp_path, channels):
    path = examples.write_csv(tmp_path / "units_row.txt", channels, units="row", delimiter=";")
    _check_round_trip(path, channels, time_exact=True)


def test_csv_header_variants(tmp_path):
    path = tmp_path / "decimal_comma.csv"
    path.write_text("Time (ms);Trq (N m);n_In\n0;1,5;100\n1;2,5;101\n2;3,5;102\n", encoding="cp1252")
    with open_recording(path) as rec:
        assert [(c.name, c.unit, c.group) for c in rec.channels] == [("Trq", "N m", "Time"), ("n_In", "", "Time")]
        t, x = rec.read("Trq")
        np.testing.assert_array_equal(t, [0.0, 0.001, 0.002])
        np.testing.assert_array_equal(x, [1.5, 2.5, 3.5])


def test_duplicate_names_are_qualified_by_group(tmp_path):
    t1, t2 = np.arange(10) / 10.0, np.arange(5) / 5.0
    from asammdf import MDF, Signal

    mdf = MDF(version="4.10")
    mdf.append([Signal(np.ones(10), t1, name="Trq", unit="N m")])
    mdf.append([Signal(np.zeros(5), t2, name="Trq", unit="kN m")])
    mdf.save(tmp_path / "dup.mf4", overwrite=True)
    mdf.close()
    with open_recording(tmp_path / "dup.mf4") as rec:
        assert [(c.name, c.unit, c.group) for c in rec.channels] == [("Trq@0", "N m", "0"), ("Trq@1", "kN m", "1")]
        np.testing.assert_array_equal(rec.read("Trq@1")[1], np.zeros(5))


@pytest.mark.parametrize("fmt", FORMATS)
def test_format_is_sniffed_by_content_not_extension(tmp_path, channels, fmt):
    wrong = {"mdf4": ".csv", "tdms": ".mat", "mat5": ".tdms", "mat73": ".mf4", "csv": ".dat"}[fmt]
    path = examples.write_recording(tmp_path / f"renamed{wrong}", channels, fmt)
    assert sniff_format(path) == fmt
    with open_recording(path) as rec:
        assert rec.format == fmt and len(rec.channels) == 4


@pytest.mark.parametrize("fmt", FORMATS)
def test_read_window_equals_slicing_read(tmp_path, channels, fmt):
    path = _write(tmp_path, channels, fmt)
    with open_recording(path) as rec:
        for name in ("Trq_In", "Speed_Out"):
            t, x = rec.read(name)
            edges = [(0.0, 0.1), (0.1, 0.2), (0.0123, 0.3217), (t[17], t[40]), (-1.0, 0.05), (0.45, 9.0),
                     (0.2, 0.2), (5.0, 6.0), (-np.inf, np.inf)]
            for t0, t1 in edges:
                tw, xw = rec.read_window(name, t0, t1)
                keep = (t >= t0) & (t < t1)
                np.testing.assert_array_equal(tw, t[keep])
                np.testing.assert_array_equal(xw, x[keep])
            # consecutive windows tile the channel exactly
            bounds = np.linspace(0.0, 0.5, 8)
            parts = [rec.read_window(name, a, b)[1] for a, b in zip(bounds[:-1], bounds[1:])]
            np.testing.assert_array_equal(np.concatenate(parts), x[t < 0.5])


def test_mdf_read_window_reads_only_the_window(tmp_path, channels):
    path = _write(tmp_path, channels, "mdf4")
    with open_recording(path) as rec:
        calls = []
        get = rec._mdf.get

        def spy(*args, **kwargs):
            calls.append(kwargs.get("record_count"))
            return get(*args, **kwargs)

        rec._mdf.get = spy
        t, _x = rec.read_window("Trq_In", 0.1, 0.15)
        assert len(t) == 100
        assert calls == [100]  # asammdf is asked for the window's records only


@pytest.mark.parametrize("compression", (0, 2))
def test_mdf_chunked_time_scan(tmp_path, monkeypatch, compression):
    """Time stamps scanned and searched in pieces (small chunks and index stride here):
    irregular time stamps, windows across piece boundaries, compressed data blocks, and a
    step backwards at a chunk boundary found."""
    from asammdf import MDF, Signal

    from dampersim.rigdata.readers import mdf as mdf_reader

    monkeypatch.setattr(mdf_reader, "CHUNK_BYTES", 24 * 128)  # chunks of 128 records of 24 bytes
    monkeypatch.setattr(mdf_reader, "INDEX_STRIDE", 32)
    t = 0.25 + np.cumsum(np.random.default_rng(0).uniform(0.5e-3, 1.5e-3, 3000))
    writer = MDF(version="4.10")
    writer.append([Signal(np.sin(t), t, name="a", unit="N m"), Signal(np.cos(t), t, name="b", unit="rpm")])
    writer.save(tmp_path / "irregular.mf4", overwrite=True, compression=compression)
    bad = t.copy()
    bad[256] = bad[255]  # sample 256 starts the third chunk
    writer = MDF(version="4.10")
    writer.append([Signal(np.sin(t), bad, name="a")])
    writer.save(tmp_path / "backwards.mf4", overwrite=True, compression=compression)
    with open_recording(tmp_path / "irregular.mf4") as rec:
        assert rec.channels[0].rate_hz is None and rec.channels[0].samples == 3000
        tr, x = rec.read("a")
        np.testing.assert_array_equal(tr, t - t[0])
        for t0, t1 in [(0.0, 0.03), (0.031, 0.0312), (0.5, 1.7), (1.0, 99.0), (tr[63], tr[64]), (tr[95], tr[300])]:
            tw, xw = rec.read_window("a", t0, t1)
            keep = (tr >= t0) & (tr < t1)
            np.testing.assert_array_equal(tw, tr[keep])
            np.testing.assert_array_equal(xw, x[keep])
    with pytest.raises(InputError, match="backwards.mf4 group 0: time is not strictly increasing at sample 256"):
        open_recording(tmp_path / "backwards.mf4")


def _truncated_copy(path, tmp_path):
    data = open(path, "rb").read()
    out = tmp_path / ("cut" + os.path.splitext(path)[1])
    out.write_bytes(data[: int(len(data) * 0.6)])
    return out


@pytest.mark.parametrize("fmt", ("mdf4", "tdms", "mat5", "mat73"))
def test_truncated_file(tmp_path, channels, fmt):
    out = _truncated_copy(_write(tmp_path, channels, fmt), tmp_path)
    with pytest.raises(InputError, match=str(out)):
        open_recording(out).read("Trq_In")


def test_truncated_csv(tmp_path, channels):
    # a CSV cut inside a number of the last column still looks complete (a shorter
    # number), so cut right after a delimiter in a middle line: its last cells are missing
    data = open(_write(tmp_path, channels, "csv"), "rb").read()
    cut = data.index(b",", data.index(b"\n", len(data) // 2)) + 1
    out = tmp_path / "cut.csv"
    out.write_bytes(data[:cut])
    with pytest.raises(InputError, match=f"{out}: line .* column 2 'Trq_In': empty cell"):
        open_recording(out)


@pytest.mark.parametrize("ext", (".mf4", ".tdms", ".mat", ".csv"))
def test_garbage_bytes(tmp_path, ext):
    out = tmp_path / f"garbage{ext}"
    out.write_bytes(random.Random(0).randbytes(20000))
    with pytest.raises(InputError, match=f"{out}: unknown format"):
        open_recording(out)


# None of the five formats defines encryption or password protection of its own (MDF 4,
# TDMS, MAT v5/v7, MAT v7.3/HDF5, CSV); an encrypted file reaches us as an encrypted
# container, which is refused by name:
def test_encrypted_container(tmp_path, channels):
    src = _write(tmp_path, channels, "mdf4")
    out = tmp_path / "protected.mf4"
    with zipfile.ZipFile(out, "w") as zf:
        zf.write(src, "rec.mf4")
    data = bytearray(out.read_bytes())
    data[6] |= 0x01  # general purpose flag: encrypted, as a password-protected archive has it
    out.write_bytes(bytes(data))
    with pytest.raises(InputError, match=f"{out}: an encrypted"):
        open_recording(out)
    ole = tmp_path / "protected.csv"
    ole.write_bytes(b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1" + bytes(504))
    with pytest.raises(InputError, match=f"{ole}: an OLE2 .*password-protected"):
        open_recording(ole)


def test_non_monotonic_time_csv(tmp_path):
    out = tmp_path / "backwards.csv"
    out.write_text("time [s],Trq_In [N m]\n0.0,1\n0.1,2\n0.2,3\n0.15,4\n0.3,5\n")
    with pytest.raises(InputError, match=rf"{out} time column 'time': time is not strictly increasing at sample 3 "
                                         r"\(0.2 s then 0.15 s\)"):
        open_recording(out)


def test_non_monotonic_time_mdf(tmp_path):
    from asammdf import MDF, Signal

    t = np.array([0.0, 0.1, 0.2, 0.2, 0.4])
    mdf = MDF(version="4.10")
    mdf.append([Signal(np.arange(5.0), t, name="Trq_In", unit="N m")])
    mdf.save(tmp_path / "backwards.mf4", overwrite=True)
    mdf.close()
    with pytest.raises(InputError, match="backwards.mf4 group 0: time is not strictly increasing at sample 3"):
        open_recording(tmp_path / "backwards.mf4")


def test_unknown_channel_name(tmp_path, channels):
    path = _write(tmp_path, channels, "tdms")
    with open_recording(path) as rec:
        for call in (lambda: rec.read("Trq_Inn"), lambda: rec.read_window("Trq_Inn", 0.0, 1.0)):
            with pytest.raises(InputError, match=rf"{path}: no channel 'Trq_Inn'; accepted .*Trq_In"):
                call()
        with pytest.raises(InputError, match=f"{path}: window t0 = nan"):
            rec.read_window("Trq_In", float("nan"), 1.0)


def test_time_base_missing(tmp_path):
    from nptdms import ChannelObject, TdmsWriter

    (tmp_path / "no_time.csv").write_text("Trq_In [N m],n_In [rpm]\n1,2\n3,4\n")
    with pytest.raises(InputError, match="no_time.csv: first column 'Trq_In' is not a time column"):
        open_recording(tmp_path / "no_time.csv")
    import scipy.io

    scipy.io.savemat(tmp_path / "no_time.mat", {"Trq_In": np.ones(5)})
    with pytest.raises(InputError, match="no_time.mat: vectors Trq_In without a time vector"):
        open_recording(tmp_path / "no_time.mat")
    scipy.io.savemat(tmp_path / "no_channels.mat", {"fs": 100.0, "operator": "A. N. Other"})
    with pytest.raises(InputError, match="no_channels.mat: no numeric data channels with a time base found; accepted MAT"):
        open_recording(tmp_path / "no_channels.mat")
    with TdmsWriter(tmp_path / "no_time.tdms") as w:
        w.write_segment([ChannelObject("G", "Trq_In", np.ones(5))])
    with pytest.raises(InputError, match="no_time.tdms group 'G' channel 'Trq_In': no time base"):
        open_recording(tmp_path / "no_time.tdms")


def test_missing_and_empty_files(tmp_path):
    with pytest.raises(InputError, match="nothing.mf4: no such file"):
        open_recording(tmp_path / "nothing.mf4")
    (tmp_path / "empty.csv").write_bytes(b"")
    with pytest.raises(InputError, match="empty.csv: empty file"):
        open_recording(tmp_path / "empty.csv")
