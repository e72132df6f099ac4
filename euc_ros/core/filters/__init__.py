"""Signal filters of euc_ros (ROS-free): Savitzky-Golay smoothing with analytic derivatives.

:mod:`euc_ros.core.filters.derivatives` holds the offline filter (whole recordings, split on gaps)
and its online fixed-lag counterpart, which agree sample for sample once the lag is aligned.
"""
from euc_ros.core.filters.derivatives import (
    Derivatives,
    StreamingSavgol,
    StreamSample,
    gap_stretches,
    savgol_coefficients,
    savgol_derivatives,
    window_samples,
)

__all__ = ["Derivatives", "StreamSample", "StreamingSavgol", "gap_stretches", "savgol_coefficients",
           "savgol_derivatives",
           "window_samples"]
