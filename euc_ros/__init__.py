"""euc_ros: motion-capture processing and electric-unicycle monitoring for ROS 2 Jazzy."""

__version__ = "0.1.0"
