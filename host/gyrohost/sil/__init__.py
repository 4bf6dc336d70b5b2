"""Software in the loop: the estimator scored against the simulated rig's truth.

``gyrotens sil`` (:func:`.scoring.report`) runs the paper's schedule on the rig's truth model and
emulators (in process on a simulated clock, or through the real-time run loop) and scores the
filter's NEES and NIS against their bounds; :mod:`.montecarlo` does the same on synthetic data,
:mod:`.effects` injects the run loop's timing one effect at a time. The studies in ``studies/``
and the tests build on these.
"""
