"""euc_ros: motion-capture processing and electric-unicycle monitoring for ROS 2 Jazzy.

The short API: :func:`identify` and :func:`residual` (:mod:`euc_ros.api`) compute what the commands
``euc-ros identify`` and ``euc-ros residual`` compute, and return it with the commands' JSON.
"""

__version__ = "0.1.0"
__all__ = ["identify", "residual"]


def __getattr__(name):
    # imported on first use: ``import euc_ros`` stays light for the node executables
    if name in __all__:
        from euc_ros import api

        return getattr(api, name)
    raise AttributeError(f"module 'euc_ros' has no attribute {name!r}")
