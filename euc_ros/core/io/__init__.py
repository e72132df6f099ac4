"""Files and wire formats: Motive CSV exports, rosbag2 bags with MCAP storage, NatNet packets and CDR messages.

All read into or written from :class:`~euc_ros.core.mocap.series.MocapSeries` and plain arrays.
"""
