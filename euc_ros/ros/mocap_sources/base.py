"""The interface every source of the ``mocap_ingest`` node implements."""
from __future__ import annotations


class MocapSource:
    """One source of capture frames for the ``mocap_ingest`` node.

    The node makes the source from its parameters and calls :meth:`setup` once. The source creates
    what it needs on the node (subscriptions, timers, sockets) and then hands every frame it makes
    to the node:

    ==============================================  =====================================================
    node member the source uses                     for
    ==============================================  =====================================================
    ``publish_frame(frame, stamp_source=None)``     a core :class:`~euc_ros.core.mocap.frame.Frame` to publish
    ``set_bodies(bodies)``                          the bodies its frames carry, in order
    ``received`` (int, incremented)                 inputs handled (poses, datagrams, CSV frames)
    ``input_error(exc)``                            an input it could not use (an EucError: dropped, counted, warned)
    ``unexpected_error()``                          any other exception in its callbacks (a bug: logged, traceback)
    ``bodies``, ``world_up``, ``stats``             the configured bodies, the up axis, the counters
    ==============================================  =====================================================

    Parameters
    ----------
    node : MocapIngest
    config : dict
        The node's parameters.

    Attributes
    ----------
    stamp_source : int
        ``MocapFrame.STAMP_*`` of the frames (a frame may be published with another).
    rate_hz : float or None
        Frame rate of the source when known in advance [Hz]; None: measured from the frames.
    """

    stamp_source: int = 0
    rate_hz: float | None = None

    def __init__(self, node, config: dict) -> None:
        self.node = node
        self.config = config

    @property
    def hardware_id(self) -> str:
        """What the stream diagnostics concern (diagnostic_updater's hardware_id): the capture system."""
        raise NotImplementedError

    @property
    def up_axis(self) -> str | None:
        """Up axis of the world the poses were converted from (None: Z-up by the input's contract)."""
        return self.node.world_up

    def setup(self) -> None:
        """Create the subscriptions, timers or sockets; raise ConfigError naming a bad parameter."""
        raise NotImplementedError

    def counters(self) -> dict:
        """The source's counters for the stream diagnostics.

        A number under a name the node counts too is added to the node's; other names are values of their own.
        """
        return {}

    def close(self) -> None:
        """Release what :meth:`setup` opened outside the node (sockets)."""
