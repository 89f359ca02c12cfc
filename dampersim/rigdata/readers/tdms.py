"""Reader of NI TDMS recordings (npTDMS), reading only the requested samples from disk.

Layouts (per TDMS group, numeric channels; string and complex channels are not listed):

- waveform channels: the properties ``wf_increment`` (sample interval [s]) and optionally
  ``wf_start_offset`` [s] and ``wf_start_time`` (absolute start) give the time base
  ``start_time + start_offset + i * increment``. Start times are used to align groups
  only when every waveform channel of the file has one.
- a time channel in the group, named like ``time``, ``t``, ``Time``, ``time_s`` (numeric
  seconds, or TDMS timestamps), shared by the group's channels without waveform
  properties, which must have as many samples as it.

Channels of one TDMS group that share a time base form one time-base group with the
group's name as id; when a TDMS group holds several time bases, they are ``NAME:1``,
``NAME:2`` ... in channel order. Units come from the ``unit_string`` property (else
``NI_UnitDescription``, else ""); DAQmx raw data is scaled by npTDMS.

Checks on opening: every segment's lead-in must be complete and announce a segment
that ends inside the file (npTDMS alone would read a truncated file with a warning).
Memory: the file stays open (``TdmsFile.open``); opening reads the metadata and streams
time channels once in chunks of 2^20 samples; ``read_window`` reads only the window's
samples (``read_data(offset, length)``).
"""

from __future__ import annotations

import math
import struct

import numpy as np

from dampersim.errors import InputError
from dampersim.rigdata.readers import Recording, SampledTime, UniformTime, _one_line, is_time_name

ACCEPTED_LAYOUT = ("accepted are TDMS channels with waveform properties (wf_increment) or a time channel "
                   "(time, t, Time, time_s) in their group")
_BIG_ENDIAN = 1 << 6
_INCOMPLETE = 0xFFFFFFFFFFFFFFFF
CHUNK = 1 << 20


def check_segments(path: str) -> None:
    """InputError when a segment lead-in is cut or a segment ends beyond the end of the file."""
    import os

    size = os.path.getsize(path)
    pos = 0
    with open(path, "rb") as fh:
        while pos < size:
            fh.seek(pos)
            lead = fh.read(28)
            if len(lead) < 28:
                raise InputError(f"{path}: truncated TDMS file: segment header at byte {pos} is cut "
                                 f"({len(lead)} of 28 bytes); {ACCEPTED_LAYOUT}")
            if lead[:4] != b"TDSm":
                raise InputError(f"{path}: damaged TDMS file: no segment header at byte {pos}; {ACCEPTED_LAYOUT}")
            toc = int.from_bytes(lead[4:8], "little")
            _version, next_offset, _raw = struct.unpack((">" if toc & _BIG_ENDIAN else "<") + "IQQ", lead[8:28])
            if next_offset == _INCOMPLETE:
                raise InputError(f"{path}: incomplete TDMS file: the segment at byte {pos} was never finished "
                                 "(the writer stopped); accepted are complete TDMS files")
            end = pos + 28 + next_offset
            if end > size:
                raise InputError(f"{path}: truncated TDMS file: the segment at byte {pos} needs {end} bytes, "
                                 f"the file has {size}; accepted are complete TDMS files")
            pos = end


def _numeric(channel) -> bool:
    dtype = getattr(channel, "dtype", None)
    return dtype is not None and np.dtype(dtype).kind in "iuf"


def _unit(channel) -> str:
    props = channel.properties
    return str(props.get("unit_string") or props.get("NI_UnitDescription") or "")


class TdmsRecording(Recording):
    """A TDMS file opened with npTDMS in streaming mode (module doc: layouts, checks)."""

    format = "tdms"
    accepted = ACCEPTED_LAYOUT

    def __init__(self, path):
        super().__init__(path)
        self._file = None
        check_segments(self.path)
        from nptdms import TdmsFile

        try:
            self._file = TdmsFile.open(self.path)
        except Exception as exc:  # noqa: BLE001 - any failure to parse is bad input
            raise InputError(f"{self.path}: not a readable TDMS file ({_one_line(exc)})") from None
        self._parse(self._scan, "TDMS", ACCEPTED_LAYOUT)

    def _scan(self):
        groups = self._file.groups()
        waveform = [c for g in groups for c in g.channels() if _numeric(c) and "wf_increment" in c.properties]
        starts = [c.properties.get("wf_start_time") for c in waveform]
        use_start_time = bool(starts) and all(isinstance(s, np.datetime64) for s in starts)
        reference = min(starts) if use_start_time else None
        self._ts_reference = reference  # absolute time of 0 s for TDMS timestamp time channels
        for g in groups:
            channels = list(g.channels())
            time_channels = [c for c in channels if is_time_name(c.name) and "wf_increment" not in c.properties]
            if len(time_channels) > 1:
                raise InputError(f"{self.path} group {g.name!r}: several time channels "
                                 f"({', '.join(c.name for c in time_channels)}); accepted is one per group")
            shared = None
            keyed: dict = {}  # time-base key -> (TimeBase, [channels])
            for c in channels:
                if any(c is tc for tc in time_channels) or not _numeric(c):
                    continue
                props = c.properties
                where = f"{self.path} group {g.name!r} channel {c.name!r}"
                n = len(c)
                if "wf_increment" in props:
                    step = float(props["wf_increment"])
                    start = float(props.get("wf_start_offset", 0.0))
                    if use_start_time:
                        start += float((props["wf_start_time"] - reference) / np.timedelta64(1, "s"))
                    key = ("wf", start, step, n)
                    if key not in keyed:
                        keyed[key] = (UniformTime(start, step, n, where=where), [])
                elif time_channels:
                    tc = time_channels[0]
                    if shared is None:
                        shared = self._time_channel(g, tc)
                    if n != shared.samples:
                        raise InputError(f"{where}: {n} samples, time channel {tc.name!r} has {shared.samples}; "
                                         "accepted are channels as long as their group's time channel")
                    key = ("time", tc.name)
                    keyed.setdefault(key, (shared, []))
                else:
                    raise InputError(f"{where}: no time base (no waveform properties, no time channel in the group); "
                                     f"{ACCEPTED_LAYOUT}")
                keyed[key][1].append(c)
            for k, (tb, members) in enumerate(keyed.values(), start=1):
                gid = g.name if len(keyed) == 1 else f"{g.name}:{k}"
                for c in members:
                    self._add(c.name, _unit(c), gid, tb, c)
        self._finish()

    def _time_channel(self, group, channel):
        where = f"{self.path} group {group.name!r} time channel {channel.name!r}"
        dtype = np.dtype(channel.dtype) if getattr(channel, "dtype", None) is not None else None
        if dtype is None or dtype.kind not in "iufM":
            raise InputError(f"{where}: type {dtype}; accepted are numeric seconds or TDMS timestamps")
        scale = 1.0
        unit = _unit(channel).strip().lower()
        if dtype.kind != "M":
            scale = {"": 1.0, "s": 1.0, "sec": 1.0, "ms": 1e-3, "us": 1e-6, "µs": 1e-6}.get(unit, math.nan)
            if math.isnan(scale):
                raise InputError(f"{where}: unit {unit!r}; accepted are s, ms, us")
        if dtype.kind == "M" and self._ts_reference is None and len(channel):
            self._ts_reference = channel.read_data(offset=0, length=1)[0]
        reference = self._ts_reference

        def read_raw(lo, hi):
            raw = channel.read_data(offset=lo, length=hi - lo)
            if dtype.kind == "M":
                return (raw - reference) / np.timedelta64(1, "s")
            return np.asarray(raw, dtype=np.float64) * scale

        return SampledTime(read_raw, len(channel), where, chunk=CHUNK)

    def _values(self, handle, lo, hi):
        if hi <= lo:
            return np.empty(0)
        return handle.read_data(offset=lo, length=hi - lo, scaled=True)

    def _close(self):
        if self._file is not None:
            self._file.close()
            self._file = None
