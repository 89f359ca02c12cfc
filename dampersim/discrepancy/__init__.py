"""The discrepancy workflow: compare a measured campaign with the model, calibrate, locate
the gap, name the missing physical effect, add it and show the gap shrink.

Modules: campaign (measured data on disk), drive (running the model on measured input),
effects (the library of candidate effects), diagnose (the workflow itself) and synth
(synthetic campaigns with a hidden effect, for testing the workflow).
"""
