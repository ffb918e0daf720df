"""Post-processing of time series: statistics of periodic signals as FSI benchmarks define them.

Depends on NumPy only; used by the validation commands, probes and sweeps.
"""

from elastoflow.analysis._periodic import PeriodicStatistics, periodic_statistics

__all__ = ["PeriodicStatistics", "periodic_statistics"]
