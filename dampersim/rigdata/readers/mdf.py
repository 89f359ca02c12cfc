"""Reader of ASAM MDF 4.x recordings (asammdf), reading time windows without loading channels.

Layout: every MDF4 channel group (data group) with a master channel of time
synchronisation (a stored or virtual time channel) is one time-base group; the group id
is the group's index in the file ("0", "1", ...). Its numeric scalar channels are listed
with the unit of their metadata (asammdf ``get_channel_unit``); conversion rules are
applied, so values are physical values. Channels that are not numeric scalars (text,
byte arrays, structures such as bus frames) are not listed; invalidation bits are not
applied. A group whose master is not time (angle, distance, index) or that has no
master is an InputError.

Checks on opening: the block chains (data groups, channel groups, channels and their
data blocks) must lie inside the file, so a truncated file is an InputError naming the
block that is cut, not a short read later; then every group's time stamps are streamed
once (one chunk of records at a time) to check that they increase strictly and to decide
whether they are uniform.

Memory: the file is read through a file object (asammdf would memory-map a path, and the
pages read would stay resident while the file is open). Opening reads the block metadata
and then one chunk of records (about 8 MB) at a time, keeping every 4096th time stamp.
``read_window`` finds the first and last record by reading 4096 time stamps each, then
asks asammdf for exactly those records (``get(group=, index=,
record_offset=, record_count=)``); asammdf reads the data blocks that hold them, so the
peak memory of a window is about (records in the window) x (record size of the group,
all its channels) plus the two float64 output arrays, whatever the size of the file.
``read`` of a whole channel needs the whole group's records once.
"""

from __future__ import annotations

import gc
import os
import struct
import sys

import numpy as np

from dampersim.errors import InputError
from dampersim.rigdata.readers import Recording, SampledTime, _one_line

ACCEPTED_LAYOUT = ("accepted are finalised MDF 4.x files whose channel groups have a time master channel "
                   "and numeric channels")
#: bytes of records read per chunk while scanning time stamps
CHUNK_BYTES = 8 << 20
#: every INDEX_STRIDE-th time stamp is kept to find a window's records
INDEX_STRIDE = 4096
_NUMERIC_DATA_TYPES = (0, 1, 2, 3, 4, 5)  # unsigned/signed integer, IEEE float, little/big endian
_NUMERIC_CONVERSIONS = (0, 1, 2, 3, 4, 5, 6)  # identity, linear, rational, algebraic, tables, range->value
_SYNC_TIME = 1
_MAX_BLOCKS = 10_000_000


def _check_blocks(path: str) -> None:
    """InputError when a block of the group chains or their data lies outside the file."""
    size = os.path.getsize(path)
    seen: set[int] = set()

    with open(path, "rb") as fh:
        def block(address: int, what: str):
            if address in seen:
                return None
            if len(seen) > _MAX_BLOCKS:
                raise InputError(f"{path}: more than {_MAX_BLOCKS} MDF blocks (damaged link chain); {ACCEPTED_LAYOUT}")
            seen.add(address)
            if address + 24 > size:
                raise InputError(f"{path}: truncated MDF file: the {what} block at byte {address} lies beyond "
                                 f"the end of the file ({size} bytes); {ACCEPTED_LAYOUT}")
            fh.seek(address)
            head = fh.read(24)
            ident, length, nlinks = head[:4], *struct.unpack("<QQ", head[8:24])
            if not ident.startswith(b"##"):
                raise InputError(f"{path}: damaged MDF file: no block header at byte {address} ({what}); {ACCEPTED_LAYOUT}")
            if address + length > size or nlinks * 8 + 24 > length:
                raise InputError(f"{path}: truncated MDF file: the {ident[2:].decode('ascii', 'replace')} block at byte "
                                 f"{address} needs {length} bytes, the file ends after {size - address}; {ACCEPTED_LAYOUT}")
            links = struct.unpack(f"<{nlinks}Q", fh.read(8 * nlinks)) if nlinks else ()
            return ident[2:], links

        def data(address: int, what: str):
            while address:
                got = block(address, what)
                if got is None:
                    return
                ident, links = got
                if ident == b"HL":
                    address = links[0] if links else 0
                elif ident == b"DL":
                    for sub in links[1:]:
                        if sub:
                            block(sub, what)
                    address = links[0] if links else 0
                else:
                    return

        fh.seek(64)
        head = fh.read(24)
        if len(head) < 24 or head[:4] != b"##HD":
            raise InputError(f"{path}: damaged MDF file: no header block at byte 64; {ACCEPTED_LAYOUT}")
        _ident, hd_links = block(64, "header")
        dg = hd_links[0] if hd_links else 0
        while dg:
            got = block(dg, "data group")
            if got is None:
                break
            _ident, dl = got
            data(dl[2] if len(dl) > 2 else 0, "data")
            cg = dl[1] if len(dl) > 1 else 0
            while cg:
                got = block(cg, "channel group")
                if got is None:
                    break
                _ident, cl = got
                cn = cl[1] if len(cl) > 1 else 0
                while cn:
                    got = block(cn, "channel")
                    if got is None:
                        break
                    cn = got[1][0] if got[1] else 0
                cg = cl[0] if cl else 0
            dg = dl[0] if dl else 0


class _quiet_failed_open:
    """asammdf's MDF4.__del__ complains on stderr about objects whose constructor failed;
    those complaints are silenced (and only those) while a failed open is collected."""

    def __enter__(self):
        self._hook = sys.unraisablehook

        def hook(unraisable, previous=self._hook):
            if not str(getattr(unraisable.object, "__module__", "") or "").startswith("asammdf"):
                previous(unraisable)

        sys.unraisablehook = hook
        return self

    def __exit__(self, *exc):
        gc.collect()
        sys.unraisablehook = self._hook
        return False


class MdfRecording(Recording):
    """An MDF 4.x file opened with asammdf (module doc: layout, checks, memory)."""

    format = "mdf4"
    accepted = ACCEPTED_LAYOUT

    def __init__(self, path):
        super().__init__(path)
        self._mdf = None
        self._fh = None
        _check_blocks(self.path)
        from asammdf import MDF

        error = None
        with _quiet_failed_open():
            try:
                # a file object, not the path: asammdf would memory-map a path, and every page
                # read would then stay resident for as long as the file is open
                self._fh = open(self.path, "rb")
                self._mdf = MDF(self._fh)
            except Exception as exc:  # noqa: BLE001 - any failure to parse is bad input
                error = _one_line(exc)
            if error is not None:
                self._close()
                raise InputError(f"{self.path}: not a readable MDF 4.x file ({error}); {ACCEPTED_LAYOUT}")
        self._parse(self._scan, "MDF", ACCEPTED_LAYOUT)

    def _scan(self):
        mdf = self._mdf
        for gi, group in enumerate(mdf.groups):
            cg = group.channel_group
            if group.channel_group.flags & 0x1:  # VLSD channel group: variable-length data of another group
                continue
            data_channels = []
            for ci, ch in enumerate(group.channels):
                if ci == mdf.masters_db.get(gi):
                    continue
                if ch.channel_type != 0 or ch.data_type not in _NUMERIC_DATA_TYPES or ch.component_addr:
                    continue  # not a fixed-length numeric scalar
                conv = ch.conversion
                if conv is not None and conv.conversion_type not in _NUMERIC_CONVERSIONS:
                    continue
                data_channels.append((ci, ch))
            if not data_channels:
                continue
            where = f"{self.path} group {gi}"
            master = mdf.masters_db.get(gi)
            if master is None:
                raise InputError(f"{where}: channel group without a master (time) channel; {ACCEPTED_LAYOUT}")
            mch = group.channels[master]
            if mch.sync_type != _SYNC_TIME:
                raise InputError(f"{where}: master channel {mch.name!r} is not time (sync type {mch.sync_type}); "
                                 f"{ACCEPTED_LAYOUT}")
            samples = int(cg.cycles_nr)
            record = max(int(cg.samples_byte_nr) + int(cg.invalidation_bytes_nr), 1)

            def read_master(lo, hi, gi=gi):
                return self._mdf.get_master(gi, record_offset=lo, record_count=hi - lo)

            tb = SampledTime(read_master, samples, where, chunk=max(16, CHUNK_BYTES // record),
                              stride=INDEX_STRIDE)
            for ci, ch in data_channels:
                unit = mdf.get_channel_unit(group=gi, index=ci)
                self._add(ch.name, unit, str(gi), tb, (gi, ci))
        self._finish()

    def _slice(self, entry, lo, hi):
        if hi <= lo:
            return np.empty(0), np.empty(0)
        gi, ci = entry.handle
        sig = self._mdf.get(group=gi, index=ci, record_offset=lo, record_count=hi - lo, skip_channel_validation=True)
        return sig.timestamps - entry.time.origin, sig.samples

    def _close(self):
        if self._mdf is not None:
            self._mdf.close()
            self._mdf = None
        if self._fh is not None:
            self._fh.close()
            self._fh = None
