"""Import of real rig recordings into a measured campaign folder.

Rig data acquisition writes ASAM MDF4, NI TDMS, MATLAB MAT (v5/v7 and v7.3) and wide CSV
files, each with its own channel names, units and sample rates per channel group, often
one long recording per run. This package turns such files into the campaign folder format
of :mod:`dampersim.discrepancy.campaign`.

Modules:

- ``readers``: one open source file as a :class:`~dampersim.rigdata.readers.Recording`
  (channel list with names, units, time-base groups and sample rates; reading a channel
  whole or a time window of it), format sniffing by content and one reader per format
  (``readers.mdf``, ``readers.tdms``, ``readers.mat``, ``readers.csv``).
- ``examples``: writers of given channel time series to every supported format, for tests
  and for ``scripts/make_rig_examples.py``.
- ``mapping``: file channel names and units to campaign columns.
- ``units``: unit texts of rig channels converted into the campaign's units.
- ``resample``: channels of different time bases onto one uniform time base.
- ``segment``: long recordings cut into test points (plateaus, ramps).
- ``importer``: the import of recordings into a campaign folder and its command line.

Importing this package imports nothing heavy; each reader imports its third-party
library (asammdf, npTDMS, scipy.io, h5py, pandas) when a file of its format is opened.
The package never imports Dash and, of dampersim, only ``errors``, ``units``, ``signal``,
``fileio`` and ``discrepancy.campaign``.
"""
