"""Example rig recordings: given channel time series written in every supported file format.

A channel set is a dict ``name -> (t, x, unit)``: time ``t`` [s] (1-D, strictly
increasing), values ``x`` in the unit named by the text ``unit`` (any unit; the writers
store values as given, in their dtype: float64 stays float64, float32 stays float32).
Channels whose time vectors are equal form one group (one time base); a set may hold
several groups (sample rates). Group names in the files are ``Group1``, ``Group2`` ... in
order of first appearance (MDF4 numbers its channel groups itself).

Writers, one per format of :mod:`dampersim.rigdata.readers` (every file is written
atomically: it appears whole or not at all):

- :func:`write_mdf4`: asammdf ``MDF.append(Signal(...))``, one channel group per group.
- :func:`write_tdms`: one TDMS group per group, waveform properties (``wf_start_offset``,
  ``wf_increment``) for uniform time bases, else (or with ``time_channel=True``) a ``Time``
  channel in the group; units in ``unit_string``.
- :func:`write_mat5` / :func:`write_mat73`: MAT v5 (scipy.io) or v7.3 (HDF5 with the
  MATLAB 512-byte header in the userblock), in one of the layouts the MAT reader accepts:
  "flat", "groups", "channels" (``channel_time`` "vector" or "rate"), "auto" = flat for one
  group, else group structs.
- :func:`write_csv`: one time column per group followed by its channels, units in the
  header (``name [unit]``) or in a second row; values with 17 significant digits (float64
  round trip is exact); shorter groups end in empty cells.

:func:`demo_channels` and :func:`long_recording_channels` make synthetic rig signals to write, with
non-standard channel names and units (torque in kN m and N m, speeds in rpm and rad/s) at
two sample rates.
"""

from __future__ import annotations

import math
import re
import time

import numpy as np

from dampersim.errors import InputError
from dampersim.fileio import atomic_write, write_text_atomic
from dampersim.rigdata.readers import is_time_name

MAT_LAYOUTS = ("auto", "flat", "groups", "channels")
_MATLAB_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,62}$")
_UNIFORM = 1e-9  # relative spread of the interval up to which TDMS gets waveform properties


def time_groups(channels: dict) -> list:
    """Channels grouped by equal time vectors: ``[(group name, t [s], [channel names]), ...]``."""
    groups: list = []
    for name, item in channels.items():
        if not isinstance(item, (tuple, list)) or len(item) != 3:
            raise InputError(f"channel {name!r}: accepted is a tuple (t [s], values, unit text)")
        t, x, _unit = item
        t = np.asarray(t, dtype=np.float64)
        if t.ndim != 1 or np.shape(x) != t.shape or t.size < 2 or not np.all(np.diff(t) > 0):
            raise InputError(f"channel {name!r}: accepted are 1-D t and values of equal length (>= 2), t increasing")
        for _g, gt, members in groups:
            if gt.shape == t.shape and np.array_equal(gt, t):
                members.append(name)
                break
        else:
            groups.append((f"Group{len(groups) + 1}", t, [name]))
    if not groups:
        raise InputError("no channels to write; accepted is a dict name -> (t, values, unit)")
    return groups


def _values(channels, name):
    x = np.asarray(channels[name][1])
    return x if x.dtype.kind == "f" else x.astype(np.float64)


def _uniform_step(t):
    step = (t[-1] - t[0]) / (t.size - 1)
    return step if np.max(np.abs(np.diff(t) - step)) <= _UNIFORM * step else None


# -- MDF4 -------------------------------------------------------------------------------

def write_mdf4(path, channels: dict) -> str:
    """Write ``channels`` as an MDF 4.10 file, one channel group per time base."""
    from asammdf import MDF, Signal

    def write(tmp):
        mdf = MDF(version="4.10")
        try:
            for gname, t, members in time_groups(channels):
                signals = [Signal(samples=_values(channels, n), timestamps=t, name=n, unit=str(channels[n][2]))
                           for n in members]
                mdf.append(signals, acq_name=gname, comment=gname)
            mdf.save(tmp, overwrite=True)
        finally:
            mdf.close()

    return atomic_write(path, write, suffix=".mf4")


# -- TDMS -------------------------------------------------------------------------------

def write_tdms(path, channels: dict, time_channel: bool = False) -> str:
    """Write ``channels`` as a TDMS file: waveform channels, or a ``Time`` channel [s] per
    group when ``time_channel`` is true or the time base is not uniform."""
    from nptdms import ChannelObject, GroupObject, RootObject, TdmsWriter

    objects = [RootObject({"title": "dampersim rig example"})]
    for gname, t, members in time_groups(channels):
        objects.append(GroupObject(gname))
        step = None if time_channel else _uniform_step(t)
        if step is None:
            objects.append(ChannelObject(gname, "Time", t, properties={"unit_string": "s"}))
        for n in members:
            props = {"unit_string": str(channels[n][2])}
            if step is not None:
                props.update(wf_start_offset=float(t[0]), wf_increment=float(step), wf_samples=int(t.size))
            objects.append(ChannelObject(gname, n, _values(channels, n), properties=props))

    def write(tmp):
        with TdmsWriter(tmp) as writer:
            writer.write_segment(objects)

    return atomic_write(path, write, suffix=".tdms")


# -- MAT --------------------------------------------------------------------------------

def _mat_tree(channels: dict, layout: str, channel_time: str) -> dict:
    """Variables of a MAT-file in ``layout``; vectors as columns (N x 1) as MATLAB stores
    rig data, texts as str, structs as dicts."""
    if layout not in MAT_LAYOUTS:
        raise InputError(f"MAT layout {layout!r}: accepted are {', '.join(MAT_LAYOUTS)}")
    if channel_time not in ("vector", "rate"):
        raise InputError(f"channel_time {channel_time!r}: accepted are vector and rate")
    groups = time_groups(channels)
    for name in channels:
        if not _MATLAB_NAME.match(name) or name in ("units", "data") or is_time_name(name):
            raise InputError(f"channel {name!r}: accepted in MAT-files are MATLAB names (letter, then letters, "
                             "digits, _; at most 63) other than units, data and time names (t, time, time_s)")
    if layout == "auto":
        layout = "flat" if len(groups) == 1 else "groups"

    def col(a):
        return np.asarray(a).reshape(-1, 1)

    tree: dict = {}
    if layout == "flat":
        if len(groups) != 1:
            raise InputError(f"MAT layout 'flat' holds one time base, the channels have {len(groups)}; "
                             "accepted layouts for several are groups and channels")
        _g, t, members = groups[0]
        tree["time"] = col(t)
        tree.update({n: col(_values(channels, n)) for n in members})
        tree["units"] = {n: str(channels[n][2]) for n in members}
    elif layout == "groups":
        for gname, t, members in groups:
            node = {"time": col(t)}
            node.update({n: col(_values(channels, n)) for n in members})
            node["units"] = {n: str(channels[n][2]) for n in members}
            tree[gname] = node
    else:
        for n, (t, _x, unit) in channels.items():
            t = np.asarray(t, dtype=np.float64)
            node = {"data": col(_values(channels, n)), "unit": str(unit)}
            step = _uniform_step(t) if channel_time == "rate" else None
            if channel_time == "rate" and step is None:
                raise InputError(f"channel {n!r}: channel_time 'rate' needs a uniform time base")
            if step is None:
                node["time"] = col(t)
            else:
                node["sample_rate"] = 1.0 / step
                if t[0] != 0.0:
                    node["start_time"] = float(t[0])
            tree[n] = node
    return tree


def write_mat5(path, channels: dict, layout: str = "auto", channel_time: str = "vector") -> str:
    """Write ``channels`` as a MAT v5 file (scipy.io.savemat) in ``layout`` (module doc)."""
    import scipy.io

    tree = _mat_tree(channels, layout, channel_time)
    return atomic_write(path, lambda tmp: scipy.io.savemat(tmp, tree, format="5"), suffix=".mat")


def mat73_header() -> bytes:
    """The 128-byte MATLAB 7.3 MAT-file header (text, subsystem offset, version, endian)."""
    text = ("MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: "
            + time.strftime("%a %b %d %H:%M:%S %Y") + " HDF5 schema 1.00 .")
    return text.encode("ascii").ljust(116, b" ")[:116] + b"\x00" * 8 + b"\x00\x02" + b"IM"


def _h5_put(parent, name: str, value) -> None:
    if isinstance(value, dict):
        group = parent.create_group(name, track_order=True)
        group.attrs["MATLAB_class"] = np.bytes_("struct")
        for key, item in value.items():
            _h5_put(group, key, item)
        return
    if isinstance(value, str):
        if not value:
            ds = parent.create_dataset(name, data=np.zeros(2, dtype=np.uint64))
            ds.attrs["MATLAB_empty"] = np.uint8(1)
        else:
            ds = parent.create_dataset(name, data=np.array([[ord(c)] for c in value], dtype=np.uint16))
            ds.attrs["MATLAB_int_decode"] = np.int32(2)
        ds.attrs["MATLAB_class"] = np.bytes_("char")
        return
    a = np.asarray(value)
    a = a.astype(np.float64) if a.dtype.kind != "f" else a
    # MATLAB is column-major: an N x 1 column vector is stored as HDF5 shape (1, N)
    ds = parent.create_dataset(name, data=np.ascontiguousarray(a.reshape(-1, 1).T) if a.ndim else a.reshape(1, 1))
    ds.attrs["MATLAB_class"] = np.bytes_("single" if a.dtype == np.float32 else "double")


def write_mat73(path, channels: dict, layout: str = "auto", channel_time: str = "vector") -> str:
    """Write ``channels`` as a MAT v7.3 file (HDF5 with the 512-byte MATLAB userblock)."""
    import h5py

    tree = _mat_tree(channels, layout, channel_time)

    def write(tmp):
        with h5py.File(tmp, "w", userblock_size=512, track_order=True) as f:
            for key, value in tree.items():
                _h5_put(f, key, value)
        with open(tmp, "r+b") as fh:
            fh.write(mat73_header().ljust(512, b"\x00"))

    return atomic_write(path, write, suffix=".mat")


# -- CSV --------------------------------------------------------------------------------

def write_csv(path, channels: dict, units: str = "header", delimiter: str = ",") -> str:
    """Write ``channels`` as a wide CSV: per group a time column [s] (``time``, or
    ``time_1``, ``time_2`` ... for several groups) and its channels; ``units`` "header"
    (``name [unit]``) or "row" (a second row of units)."""
    if units not in ("header", "row"):
        raise InputError(f"units {units!r}: accepted are header and row")
    if delimiter not in (",", ";", "\t"):
        raise InputError(f"delimiter {delimiter!r}: accepted are ',', ';' and tab")
    groups = time_groups(channels)
    for name in channels:
        if is_time_name(name):
            raise InputError(f"channel {name!r}: accepted in CSV are channel names other than time names "
                             "(t, time, time_s), which start a new group")
    names, unit_row, columns = [], [], []
    for k, (_g, t, members) in enumerate(groups, start=1):
        for name, unit, values in [("time" if len(groups) == 1 else f"time_{k}", "s", t)] + \
                [(n, str(channels[n][2]), _values(channels, n)) for n in members]:
            if any(c in name for c in (delimiter, '"', "\n")) or any(c in unit for c in (delimiter, '"', "\n", "]")):
                raise InputError(f"channel {name!r} unit {unit!r}: accepted in CSV are names and units without "
                                 "the delimiter, quotes, line breaks or ']'")
            names.append(f"{name} [{unit}]" if units == "header" else name)
            unit_row.append(unit)
            columns.append(np.char.mod("%.17g", np.asarray(values, dtype=np.float64)).tolist())
    rows = max(len(c) for c in columns)
    columns = [c + [""] * (rows - len(c)) for c in columns]
    lines = [delimiter.join(names)] + ([delimiter.join(unit_row)] if units == "row" else [])
    lines += [delimiter.join(row) for row in zip(*columns)]
    return write_text_atomic(path, "\n".join(lines) + "\n")


WRITERS = {"mdf4": write_mdf4, "tdms": write_tdms, "mat5": write_mat5, "mat73": write_mat73, "csv": write_csv}
EXTENSIONS = {"mdf4": ".mf4", "tdms": ".tdms", "mat5": ".mat", "mat73": ".mat", "csv": ".csv"}


def write_recording(path, channels: dict, fmt: str) -> str:
    """Write ``channels`` to ``path`` in format ``fmt`` (a key of :data:`WRITERS`)."""
    if fmt not in WRITERS:
        raise InputError(f"format {fmt!r}: accepted are {', '.join(WRITERS)}")
    return WRITERS[fmt](path, channels)


# -- synthetic rig signals ----------------------------------------------------------------

def _settle(command, rate_hz: float, natural_hz: float = 1.5, damping: float = 0.6):
    """``command`` followed by a second-order lag (steps settle with a small overshoot)."""
    from scipy import signal

    wn = 2.0 * math.pi * natural_hz
    system = signal.cont2discrete(([wn * wn], [1.0, 2.0 * damping * wn, wn * wn]), 1.0 / rate_hz, method="bilinear")
    b, a = np.ravel(system[0]), np.ravel(system[1])
    zi = signal.lfilter_zi(b, a) * command[0]
    return signal.lfilter(b, a, command, zi=zi)[0]


def long_recording_channels(program=None, fast_hz: float = 2000.0, slow_hz: float = 500.0, seed: int = 1) -> dict:
    """Synthetic rig run: torque channels at ``fast_hz`` [Hz], speed channels at ``slow_hz``.

    ``program``: sequence of ``(duration [s], speed [rpm], torque [N m])`` plateaus, a
    torque of ``(start, end)`` being a linear torque ramp [N m] over the segment. Speed and
    mean torque follow the program with settling transients; the input torque carries
    order 2 content (twice the rotation frequency, 30 % of the mean torque plus 40 N m),
    the output torque a damped copy of it. Channels: ``Trq_In`` [kN m], ``Torque_Output``
    [N m] (fast group), ``n_In`` [rpm], ``Speed_Out`` [rad/s] and ``Windup_Angle`` [rad]
    (slow group; the windup of a 381 N m/rad damper, the default set's outer stage).
    """
    if program is None:
        program = ((4.0, 1000.0, 100.0), (5.0, 1500.0, 200.0), (5.0, 2000.0, 150.0),
                   (8.0, 1200.0, (-200.0, 300.0)), (5.0, 1800.0, 250.0))
    rng = np.random.default_rng(seed)
    duration = float(sum(seg[0] for seg in program))
    t = np.arange(int(round(duration * fast_hz))) / fast_hz
    speed_cmd = np.empty_like(t)
    torque_cmd = np.empty_like(t)
    start = 0.0
    for seg_s, rpm, torque in program:
        m = (t >= start) & (t < start + seg_s)
        speed_cmd[m] = rpm
        if isinstance(torque, (tuple, list)):
            torque_cmd[m] = torque[0] + (torque[1] - torque[0]) * (t[m] - start) / seg_s
        else:
            torque_cmd[m] = torque
        start += seg_s
    rpm = _settle(speed_cmd, fast_hz, natural_hz=0.8)
    mean_torque = _settle(torque_cmd, fast_hz, natural_hz=2.0)
    angle = np.cumsum(rpm * (2.0 * math.pi / 60.0)) / fast_hz  # rotation angle [rad]
    amp = 0.3 * np.abs(mean_torque) + 40.0
    trq_in = mean_torque + amp * np.sin(2.0 * angle) + rng.normal(0.0, 2.0, t.size)
    trq_out = mean_torque + 0.25 * amp * np.sin(2.0 * angle - 0.6) + rng.normal(0.0, 1.0, t.size)
    stride = int(round(fast_hz / slow_hz))
    ts = t[::stride]
    n_in = rpm[::stride] + 3.0 * np.sin(2.0 * angle[::stride]) + rng.normal(0.0, 0.5, ts.size)
    speed_out = (rpm[::stride] - 2.0) * (2.0 * math.pi / 60.0) + rng.normal(0.0, 0.02, ts.size)
    windup = mean_torque[::stride] / 381.0 + rng.normal(0.0, 1e-4, ts.size)
    return {
        "Trq_In": (t, trq_in / 1000.0, "kN m"),
        "Torque_Output": (t, trq_out, "N m"),
        "n_In": (ts, n_in, "rpm"),
        "Speed_Out": (ts, speed_out, "rad/s"),
        "Windup_Angle": (ts, windup, "rad"),
    }


def demo_channels(duration_s: float = 1.0, fast_hz: float = 2000.0, slow_hz: float = 500.0, seed: int = 1) -> dict:
    """A short test-point recording (``duration_s`` [s] at 1500 rpm and 200 N m) with the
    torque and speed channels of :func:`long_recording_channels` (a test point needs no
    windup); ``Speed_Out`` stored as float32."""
    channels = long_recording_channels(((duration_s, 1500.0, 200.0),), fast_hz, slow_hz, seed)
    del channels["Windup_Angle"]
    t, x, unit = channels["Speed_Out"]
    channels["Speed_Out"] = (t, x.astype(np.float32), unit)
    return channels


def point_channels(point) -> dict:
    """One campaign test point (a :class:`dampersim.discrepancy.campaign.MeasuredPoint`) as rig
    channels on its own time base, with other names and units than the campaign's:
    ``Trq_In`` [kN m], ``Torque_Output`` [N m], ``n_In`` [rpm], ``Speed_Out`` [rad/s] and,
    for a ramp, ``Twist`` [deg] (the windup)."""
    t = point.time
    channels = {
        "Trq_In": (t, point.input_torque / 1000.0, "kN m"),
        "Torque_Output": (t, point.output_torque, "N m"),
        "n_In": (t, point.input_speed_rpm, "rpm"),
        "Speed_Out": (t, point.output_speed_rpm * (math.pi / 30.0), "rad/s"),
    }
    if point.windup is not None:
        channels["Twist"] = (t, np.degrees(point.windup), "deg")
    return channels


__all__ = ["WRITERS", "point_channels", "EXTENSIONS", "MAT_LAYOUTS", "time_groups", "write_mdf4", "write_tdms", "write_mat5",
           "write_mat73", "write_csv", "write_recording", "mat73_header", "demo_channels",
           "long_recording_channels"]
