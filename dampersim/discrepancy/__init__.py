"""The discrepancy workflow: compare a measured campaign with the model, calibrate, weigh
"no missing effect" against candidate effects by their evidence, add the most probable one
and show the gap shrink; say what this campaign could detect and which test to run next.

Modules: campaign (measured data on disk), campaign_write, upload (campaign zips from a
browser), drive (running the model on measured input), tracking (order coefficients of measured
points on the low-passed measured input speed), effects (the library of candidate effects),
likelihood (complex order residuals, their uncertainties, channel nuisance, robust loss),
fitting (calibration arithmetic), selection (Laplace evidence, posterior, detection
thresholds), intervals (the reported 90 % intervals, widened where leaving out a point moves a
parameter further), naming (screen, fits, evidence), shapes (the shape parameters screened,
fitted and chosen, and their priors), detect (an effect's detection threshold for the
campaign), ramps (windup curves as predictions), design (next test points), outcome (the result
record and its sentence), diagnose (the workflow itself), report and report_tables (a diagnosis
as a document, its summary rows and tables), synth, daq and truths (synthetic campaigns with
hidden effects, DAQ corruption and benchmark truths, for testing the workflow) and benchmark
(the benchmark's figures).
"""
