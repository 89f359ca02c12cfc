"""The discrepancy workflow: compare a measured campaign with the model, calibrate, locate
the gap, name the missing physical effect, add it and show the gap shrink.

Modules: campaign (measured data on disk), upload (campaign zips from a browser), drive
(running the model on measured input), tracking (order amplitudes of measured points on the
low-passed measured input speed), effects (the library of candidate effects),
diagnose (the workflow itself), report (a diagnosis as a JSON document and its summary
rows) and synth (synthetic campaigns with a hidden effect, for testing the workflow).
"""
