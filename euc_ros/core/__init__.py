"""ROS-free core of euc_ros: numpy/scipy only.

No module below this package may import rclpy, any ``*_msgs`` package, ``euc_msgs`` or
matplotlib (enforced by ``test/unit/test_core_imports.py``).
"""
