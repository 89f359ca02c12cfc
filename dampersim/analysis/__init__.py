"""Analysis of torque time series [N m]: amplitude spectra, engine-order amplitudes and the
comparison metrics between simulation and rig measurement, following [thesis] §3.4 (Hann
window spectrum of a 1.25 s record from which the first eight engine orders are picked) and
[thesis] §6.3.1 (simulation error per order, relative to the measured input amplitude). The
spectral primitives live one layer down, in :mod:`dampersim.signal`; the metrics (magnification
ratio, simulation error, campaign error table) are in :mod:`dampersim.analysis.metrics`.
"""
