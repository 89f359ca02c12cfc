"""The reader interface: one open rig recording, whatever its file format.

:func:`open_recording` recognises the format by content (:func:`sniff_format`: magic bytes
and headers, never the file name's extension) and opens the file with the reader of that
format (``mdf``, ``tdms``, ``mat``, ``csv`` in this package). Every reader returns a
:class:`Recording`:

- ``channels``: one :class:`ChannelInfo` per numeric data channel (time channels are not
  listed) with the name and unit text as stored in the file, the time-base ``group`` (the
  channels of one group share one time base), the number of samples and the sample rate
  when the time base is uniform.
- ``read(name)`` and ``read_window(name, t0, t1)`` return ``(time [s], values)`` as
  float64. Time runs from the start of the recording: the earliest first time stamp of
  all groups is 0 s, so groups keep their alignment to each other. Values are in the
  unit of the file (``ChannelInfo.unit``); converting to SI is the mapping's job.

Names are unique within a recording: a channel name stored in more than one group is
listed as ``NAME@GROUP`` for each occurrence.

Time bases are checked when the file is opened: time stamps must be finite and strictly
increasing; otherwise :class:`~dampersim.errors.InputError` names the file, the group and
the sample. Every problem with the input (missing, unreadable, truncated or encrypted
file, unknown format, undeterminable time base, unknown channel name) is an InputError
with one line naming the file and what is accepted. Readers open files read-only.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass

import numpy as np

from dampersim.errors import InputError

FORMATS = ("mdf4", "tdms", "mat5", "mat73", "csv")
ACCEPTED = ("ASAM MDF 4.x, NI TDMS, MATLAB MAT-file v5/v7 or v7.3, "
            "or delimited text (CSV) with a header row and a time column")
#: relative spread of the sample interval up to which a time base counts as uniform
UNIFORM_TOLERANCE = 1e-6
_SNIFF_BYTES = 4096
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
#: a time column/variable/channel: "t", "time", or "time" followed by a separator and a
#: suffix ("time_s", "Time 2", "time-fast"), any case
TIME_NAME = re.compile(r"^(t|time([ _.\-][\w. \-]*)?)$", re.IGNORECASE)


def is_time_name(name: str) -> bool:
    """Whether ``name`` names a time vector (``t``, ``time``, ``Time``, ``time_s``, ...)."""
    return bool(TIME_NAME.match(str(name).strip()))


@dataclass(frozen=True)
class ChannelInfo:
    """One data channel of a recording."""

    name: str  # channel name as stored in the file (NAME@GROUP when stored in several groups)
    unit: str  # unit text from the file's metadata, "" when the file has none
    group: str  # time-base id: channels of one group share one time base
    samples: int  # number of samples
    rate_hz: float | None  # sample rate [Hz] when the time base is uniform, else None


class TimeBase:
    """Time stamps of one group; ``times``/``index`` work relative to ``origin`` [s]."""

    samples: int = 0
    rate_hz: float | None = None
    first: float = math.inf  # first raw time stamp [s] (inf when empty)
    origin: float = 0.0  # raw time [s] of the start of the recording

    def times(self, lo: int, hi: int) -> np.ndarray:
        """Time [s] from the start of the recording of samples ``lo:hi``."""
        raise NotImplementedError

    def index(self, t: float) -> int:
        """Index of the first sample at or after time ``t`` [s] (``samples`` if none)."""
        raise NotImplementedError


class UniformTime(TimeBase):
    """Time stamps ``start + i * step`` [s] (waveform properties, a sample rate field)."""

    def __init__(self, start: float, step: float, samples: int, rate_hz: float | None = None, where: str = ""):
        if not (math.isfinite(start) and math.isfinite(step) and step > 0):
            raise InputError(f"{where}: time base start {start!r} s, interval {step!r} s; "
                             "accepted is a finite start and a positive sample interval")
        self.start, self.step, self.samples = float(start), float(step), int(samples)
        self.rate_hz = float(rate_hz) if rate_hz else 1.0 / self.step
        self.first = self.start if self.samples else math.inf
        self._offset = self.start

    def set_origin(self, origin: float) -> None:
        self.origin = origin
        self._offset = self.start - origin

    def times(self, lo, hi):
        return self._offset + np.arange(lo, hi, dtype=np.float64) * self.step

    def index(self, t):
        if self.samples == 0:
            return 0
        guess = (t - self._offset) / self.step
        i = int(min(max(math.ceil(guess), 0), self.samples)) if math.isfinite(guess) else (0 if guess < 0 else self.samples)

        def at(k):
            return self._offset + np.float64(k) * self.step

        while i > 0 and at(i - 1) >= t:
            i -= 1
        while i < self.samples and at(i) < t:
            i += 1
        return i


class SampledTime(TimeBase):
    """Stored time stamps [s], read through ``read_raw(lo, hi)``.

    The constructor streams through all time stamps once, ``chunk`` samples at a time
    (memory: one chunk): it checks that they are finite and strictly increasing, decides
    whether they are uniform and keeps every ``stride``-th time stamp, so that
    :meth:`index` reads only ``stride`` time stamps.
    """

    def __init__(self, read_raw, samples: int, where: str, chunk: int = 1 << 20, stride: int = 4096):
        self._read_raw = read_raw
        self.samples = int(samples)
        self.stride = max(int(stride), 2)
        chunk = -(-max(int(chunk), 1) // self.stride) * self.stride  # a multiple of stride
        starts = []
        prev = None
        dmin, dmax = math.inf, -math.inf
        last = math.nan
        for lo in range(0, self.samples, chunk):
            hi = min(lo + chunk, self.samples)
            t = np.asarray(read_raw(lo, hi), dtype=np.float64)
            if t.shape != (hi - lo,):
                raise InputError(f"{where}: {t.size} time stamps where {hi - lo} were expected at sample {lo} "
                                 "(truncated or damaged file)")
            if not np.all(np.isfinite(t)):
                k = int(np.flatnonzero(~np.isfinite(t))[0])
                raise InputError(f"{where}: time stamp {t[k]!r} at sample {lo + k}; accepted are finite time stamps [s]")
            tt, base = (t, lo) if prev is None else (np.concatenate(([prev], t)), lo - 1)
            d = np.diff(tt)
            if d.size:
                if not np.all(d > 0):
                    k = int(np.flatnonzero(~(d > 0))[0])
                    raise InputError(f"{where}: time is not strictly increasing at sample {base + k + 1} "
                                     f"({float(tt[k])!r} s then {float(tt[k + 1])!r} s); "
                                     "accepted is a strictly increasing time base")
                dmin, dmax = min(dmin, float(d.min())), max(dmax, float(d.max()))
            starts.append(t[:: self.stride].copy())
            prev, last = float(t[-1]), float(t[-1])
        self._starts_raw = np.concatenate(starts) if starts else np.empty(0)
        self._starts = self._starts_raw
        self.first = float(self._starts_raw[0]) if self.samples else math.inf
        self.rate_hz = None
        if self.samples >= 2:
            mean = (last - self.first) / (self.samples - 1)
            if mean > 0 and max(dmax - mean, mean - dmin) <= UNIFORM_TOLERANCE * mean:
                self.rate_hz = 1.0 / mean

    def set_origin(self, origin: float) -> None:
        self.origin = origin
        self._starts = self._starts_raw - origin

    def times(self, lo, hi):
        if hi <= lo:
            return np.empty(0)
        return np.asarray(self._read_raw(lo, hi), dtype=np.float64) - self.origin

    def index(self, t):
        j = int(np.searchsorted(self._starts, t, side="right")) - 1
        if j < 0:
            return 0
        lo = j * self.stride
        hi = min(lo + self.stride, self.samples)
        return lo + int(np.searchsorted(self.times(lo, hi), t, side="left"))


@dataclass(frozen=True)
class _Entry:
    info: ChannelInfo
    time: TimeBase
    handle: object  # the reader's reference to the channel's values


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 300 else text[:297] + "..."


class Recording:
    """One open source file: its data channels and reading them by name (see module doc).

    Subclasses fill the channel list with :meth:`_add` and :meth:`_finish` and implement
    :meth:`_values` (and :meth:`_close` when they hold the file open).
    """

    format = ""
    accepted = ACCEPTED  # what the reader accepts, for messages

    def __init__(self, path):
        self.path = os.path.abspath(os.fspath(path))
        self.channels: tuple[ChannelInfo, ...] = ()
        self._pending: list = []
        self._entries: dict[str, _Entry] = {}
        self._closed = False

    # -- building the channel list (readers) --
    def _add(self, name: str, unit: str, group: str, time: TimeBase, handle) -> None:
        self._pending.append((str(name), str(unit or "").strip(), str(group), time, handle))

    def _finish(self) -> None:
        """Make names unique, put the recording's start at 0 s and list the channels."""
        counts: dict[str, int] = {}
        for name, *_ in self._pending:
            counts[name] = counts.get(name, 0) + 1
        bases = {id(tb): tb for *_, tb, _h in self._pending}
        firsts = [tb.first for tb in bases.values() if tb.samples]
        origin = min(firsts) if firsts else 0.0
        for tb in bases.values():
            tb.set_origin(origin)
        entries = {}
        for name, unit, group, tb, handle in self._pending:
            key = name if counts[name] == 1 else f"{name}@{group}"
            if key in entries:
                raise InputError(f"{self.path}: channel {name!r} is stored twice in group {group!r}; "
                                 "accepted are unique channel names within a group")
            entries[key] = _Entry(ChannelInfo(key, unit, group, tb.samples, tb.rate_hz), tb, handle)
        if not entries:
            raise InputError(f"{self.path}: no numeric data channels with a time base found; {self.accepted}")
        self._entries = entries
        self.channels = tuple(e.info for e in entries.values())
        self._pending = []

    # -- reading (subclasses) --
    def _values(self, handle, lo: int, hi: int) -> np.ndarray:
        """Values of samples ``lo:hi`` of the channel ``handle`` in the file's unit."""
        raise NotImplementedError

    def _slice(self, entry: _Entry, lo: int, hi: int):
        return entry.time.times(lo, hi), self._values(entry.handle, lo, hi)

    def _close(self) -> None:
        pass

    def _parse(self, parse, what: str, accepted: str) -> None:
        """Run ``parse()`` (the reader's scan of the opened file); on any failure close the
        file and raise InputError naming it: an InputError as it is, anything else as a
        damaged ``what`` file with ``accepted`` (the layouts the reader reads)."""
        try:
            parse()
        except InputError:
            self._close()
            raise
        except Exception as exc:  # noqa: BLE001 - any failure to parse is bad input
            self._close()
            raise InputError(f"{self.path}: damaged {what} file ({_one_line(exc)}); {accepted}") from None

    # -- public interface --
    def _entry(self, name) -> _Entry:
        if self._closed:
            raise InputError(f"{self.path}: the recording is closed; open it again with open_recording")
        entry = self._entries.get(name)
        if entry is None:
            names = [c.name for c in self.channels]
            shown = ", ".join(names[:30]) + (f", ... ({len(names)} in all)" if len(names) > 30 else "")
            raise InputError(f"{self.path}: no channel {name!r}; accepted are the file's channels: {shown}")
        return entry

    def _read(self, name, entry, lo, hi):
        try:
            t, x = self._slice(entry, lo, hi)
        except InputError:
            raise
        except Exception as exc:  # noqa: BLE001 - a damaged file shows up while reading
            raise InputError(f"{self.path}: channel {name!r} samples {lo}-{hi} cannot be read ({_one_line(exc)}); "
                             "the file is damaged or truncated") from None
        t = np.asarray(t, dtype=np.float64)
        x = np.asarray(x, dtype=np.float64).reshape(-1)
        if t.shape != (hi - lo,) or x.shape != (hi - lo,):
            raise InputError(f"{self.path}: channel {name!r} gave {x.size} samples where {hi - lo} were expected "
                             "(truncated or damaged file)")
        return t, x

    def read(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """(time [s] from the start of the recording, values as float64 in the file's unit)."""
        entry = self._entry(name)
        return self._read(name, entry, 0, entry.time.samples)

    def read_window(self, name: str, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """Only the samples with ``t0 <= t < t1`` (time [s] from the start of the recording).

        Reads only that part of the file where the format allows it (MDF4, TDMS, MAT
        v7.3); see the reader modules for the memory each format needs.
        """
        entry = self._entry(name)
        for label, value in (("t0", t0), ("t1", t1)):
            if not isinstance(value, (int, float, np.integer, np.floating)) or math.isnan(value):
                raise InputError(f"{self.path}: window {label} = {value!r} for channel {name!r}; accepted is a number of seconds")
        if t1 < t0:
            raise InputError(f"{self.path}: window {t0!r} s to {t1!r} s for channel {name!r}; accepted is t0 <= t1")
        tb = entry.time
        lo = tb.index(float(t0))
        hi = max(lo, tb.index(float(t1)))
        return self._read(name, entry, lo, hi)

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            self._close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
        return False

    def __repr__(self):
        return f"<{type(self).__name__} {self.format} {self.path!r}: {len(self.channels)} channels>"


def check_readable(path) -> str:
    """Absolute path of an existing, readable, non-empty regular file, else InputError."""
    path = os.path.abspath(os.fspath(path))
    if not os.path.exists(path):
        raise InputError(f"{path}: no such file; accepted is an existing recording file ({ACCEPTED})")
    if not os.path.isfile(path):
        raise InputError(f"{path}: not a regular file; accepted is a recording file ({ACCEPTED})")
    if not os.access(path, os.R_OK):
        raise InputError(f"{path}: cannot be read (permission denied)")
    if os.path.getsize(path) == 0:
        raise InputError(f"{path}: empty file; accepted is a recording file ({ACCEPTED})")
    return path


def _zip_message(path, head: bytes) -> str:
    flags = int.from_bytes(head[6:8], "little") if len(head) >= 8 else 0
    if flags & 0x1:
        return f"{path}: an encrypted (password-protected) ZIP archive; accepted is an unencrypted recording ({ACCEPTED})"
    return f"{path}: a ZIP archive; unpack it and open the recording inside ({ACCEPTED})"


def _looks_like_text_table(head: bytes) -> bool:
    if b"\x00" in head:
        return False
    text = None
    for enc in ("utf-8-sig", "cp1252"):
        try:
            text = head.decode(enc)
            break
        except UnicodeDecodeError:
            # a multi-byte character cut at the end of the sniffed block is fine
            if enc == "utf-8-sig":
                try:
                    text = head[:-4].decode(enc)
                    break
                except UnicodeDecodeError:
                    continue
    if text is None:
        return False
    if any(ord(c) < 32 and c not in "\t\r\n" for c in text):
        return False
    first = text.lstrip().splitlines()[0] if text.strip() else ""
    return any(first.count(d) >= 1 for d in ("\t", ";", ","))


def sniff_format(path) -> str:
    """Format of the file at ``path`` by its content: "mdf4", "tdms", "mat5", "mat73" or "csv".

    The extension is not looked at. Unknown content, MDF 3, unfinalised MDF, plain HDF5,
    archives (ZIP, encrypted ZIP, gzip) and OLE2 containers (old Excel, password-protected
    Office files) are InputErrors naming the file and what is accepted.
    """
    path = check_readable(path)
    try:
        with open(path, "rb") as fh:
            head = fh.read(_SNIFF_BYTES)
            fh.seek(512)
            at512 = fh.read(8)
    except OSError as exc:
        raise InputError(f"{path}: cannot be read ({_one_line(exc)})") from None
    if head.startswith(b"MDF     "):
        version = head[8:16].decode("ascii", "replace").strip()
        if version.startswith("4."):
            return "mdf4"
        raise InputError(f"{path}: MDF version {version!r}; accepted is MDF 4.x (convert older MDF files to 4.10 first)")
    if head.startswith(b"UnFinMF "):
        raise InputError(f"{path}: unfinalised MDF file (the recording was not closed properly); "
                         "accepted are finalised MDF 4.x files (finalise it with the acquisition software)")
    if head.startswith(b"TDSm"):
        return "tdms"
    if head.startswith(b"TDSh"):
        raise InputError(f"{path}: a TDMS index file; accepted is the .tdms data file next to it")
    if head.startswith(b"MATLAB 5.0 MAT-file"):
        if len(head) < 128 or head[126:128] not in (b"IM", b"MI"):
            raise InputError(f"{path}: truncated MAT-file header; accepted is a complete MATLAB MAT-file")
        return "mat5"
    if head.startswith(b"MATLAB 7.3 MAT-file"):
        if at512 != _HDF5_SIGNATURE:
            raise InputError(f"{path}: MAT v7.3 header without HDF5 data at byte 512 (truncated or damaged file); "
                             "accepted is a complete MATLAB v7.3 MAT-file")
        return "mat73"
    if head.startswith(b"MATLAB "):
        raise InputError(f"{path}: unsupported MAT-file version {head[:20]!r}; accepted are MAT v5/v7 and v7.3")
    if head.startswith(_HDF5_SIGNATURE):
        raise InputError(f"{path}: an HDF5 file without the MATLAB 7.3 header; accepted are MAT v7.3 files ({ACCEPTED})")
    if head.startswith(b"PK\x03\x04"):
        raise InputError(_zip_message(path, head))
    if head.startswith(b"\xd0\xcf\x11\xe0\xa1\xb1\x1a\xe1"):
        raise InputError(f"{path}: an OLE2 compound file (old Excel workbook or password-protected Office document); "
                         f"accepted is {ACCEPTED}")
    if head.startswith(b"\x1f\x8b"):
        raise InputError(f"{path}: gzip-compressed; decompress it first ({ACCEPTED})")
    if _looks_like_text_table(head):
        return "csv"
    raise InputError(f"{path}: unknown format (first bytes {head[:8]!r}); accepted is {ACCEPTED}")


def open_recording(path) -> Recording:
    """Sniff the format of ``path`` and open it with the reader of that format."""
    fmt = sniff_format(path)
    if fmt == "mdf4":
        from dampersim.rigdata.readers.mdf import MdfRecording as cls
    elif fmt == "tdms":
        from dampersim.rigdata.readers.tdms import TdmsRecording as cls
    elif fmt in ("mat5", "mat73"):
        from dampersim.rigdata.readers.mat import MatRecording

        return MatRecording(path, fmt)
    else:
        from dampersim.rigdata.readers.csv import CsvRecording as cls
    return cls(path)


__all__ = ["FORMATS", "ACCEPTED", "ChannelInfo", "Recording", "TimeBase", "UniformTime", "SampledTime",
           "is_time_name", "check_readable", "sniff_format", "open_recording"]
