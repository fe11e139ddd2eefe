"""Requirements: named Signal Temporal Logic formulas checked on every run.

:mod:`.robustness` holds the quantitative STL semantics over sampled signals (numpy,
vectorized over the ensemble axis).
"""
