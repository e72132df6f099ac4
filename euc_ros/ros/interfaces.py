"""Every topic name, message type and QoS profile of the pipeline, in one place.

Topics are relative so namespaces and remaps work. Data flows one way:
``mocap/frame`` -> ``rider/state`` -> ``euc/torque`` -> diagnostics.
"""
from __future__ import annotations

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# --- topic names -------------------------------------------------------------------------------
MOCAP_FRAME = "mocap/frame"                  # euc_msgs/MocapFrame, one per capture frame
MOCAP_BODY_POSE = "mocap/{name}/pose"        # geometry_msgs/PoseStamped per rigid body
RIDER_STATE = "rider/state"                  # euc_msgs/RiderState
TORQUE = "euc/torque"                        # euc_msgs/TorqueEstimate
DIAGNOSTICS = "/diagnostics"                 # diagnostic_msgs/DiagnosticArray (absolute, ROS convention)
TF = "/tf"                                   # tf2_msgs/TFMessage
CLOCK = "/clock"                             # rosgraph_msgs/Clock
UNICYCLE_STATE = "unicycle/state"            # euc_msgs/UnicycleState
UNICYCLE_POSE = "unicycle/pose"              # geometry_msgs/PoseStamped for viewing
STEERING_COMMAND = "unicycle/command"        # euc_msgs/SteeringCommand
VRPN_PREFIX = "/vrpn_mocap"                  # live input convention <prefix>/<Body>/pose (docs/bags.md)

#: The pipeline's topics that the recorder takes by default.
PIPELINE_TOPICS = (MOCAP_FRAME, RIDER_STATE, TORQUE, DIAGNOSTICS, TF)

# --- QoS profiles ------------------------------------------------------------------------------
#: Live mocap input: best effort like the sensor-data profile (so it matches the drivers' best-effort
#: publishers as well as reliable ones), but a queue of ~1 s of poses of 14 bodies at 360 Hz: the
#: sensor profile's 5 messages per topic dropped poses whenever the node was briefly starved of CPU
#: (a loaded host), and a dropped pose is a dropped measurement.
MOCAP_INPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=400, reliability=ReliabilityPolicy.BEST_EFFORT,
                             durability=DurabilityPolicy.VOLATILE)


def mocap_input_qos(reliability: str) -> QoSProfile:
    """The live mocap input's QoS.

    :data:`MOCAP_INPUT_QOS`, or reliable (``"reliable"``) when every publisher is reliable (a bag replayed by
    ``euc-ros play``): then nothing is dropped, even on a starved host.
    """
    if reliability == "reliable":
        return QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=MOCAP_INPUT_QOS.depth,
                          reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
    return MOCAP_INPUT_QOS


#: Frames, derived estimates and transforms we publish: reliable so the recorder and the next stage lose
#: nothing. A reliable KEEP_LAST writer repairs a subscriber's losses from its own history only, so the
#: depth is how long a subscriber may be starved of CPU (its middleware threads not running) and still
#: get every message: at depth 256 a recorder stopped for S s during a 2x replay (240 frames/s) loses
#: ``240 S - 256`` frames (measured: none at 1.0 s, 73 at 1.4 s, 223 at 2.0 s). 4096 are 11 s at 360 Hz
#: and 17 s at 240 Hz, at most ~4 MB of 14-body frames per topic (nothing is allocated up front). On the
#: subscription side the depth is how far a node may fall behind before its queue drops messages.
RELIABLE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=4096, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.VOLATILE)
#: Lockstep simulation: every message matters and late joiners must still get the first step.
LOCKSTEP_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=64, reliability=ReliabilityPolicy.RELIABLE,
                          durability=DurabilityPolicy.TRANSIENT_LOCAL)
#: Diagnostics: reliable, shallow.
DIAGNOSTICS_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=10, reliability=ReliabilityPolicy.RELIABLE)
#: Simulated time (/clock): reliable, so a use_sim_time node never sees time skip a step.
CLOCK_QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)


def sanitize(name: str) -> str:
    """Turn a rigid-body name into a valid topic/frame token (``'RigidBody 01'`` -> ``'RigidBody_01'``)."""
    out = "".join(c if c.isalnum() or c == "_" else "_" for c in name.strip())
    if not out or out[0].isdigit():
        out = "b_" + out
    return out


def body_pose_topic(name: str) -> str:
    """Per-body PoseStamped topic for ``name``."""
    return MOCAP_BODY_POSE.format(name=sanitize(name))


# --- middleware event handlers -----------------------------------------------------------------
# rclpy gives every publisher and subscription default QoS-event handlers (incompatible QoS and type
# warnings), each a waitable the Python executor visits on every spin: mocap_ingest's ~20 publishers
# made each callback cost ~3x (345 vs 115 us per spin measured with 20 publishers). The pipeline's
# own topics use matching profiles by construction; the other side of a mismatch still warns.
def pub_events() -> PublisherEventCallbacks:
    """Publisher event callbacks without the default handlers (see above)."""
    return PublisherEventCallbacks(use_default_callbacks=False)


def sub_events() -> SubscriptionEventCallbacks:
    """Subscription event callbacks without the default handlers (see above)."""
    return SubscriptionEventCallbacks(use_default_callbacks=False)


def diagnostics_publisher(node):
    """Create the node's publisher of :data:`DIAGNOSTICS` (:data:`DIAGNOSTICS_QOS`, :func:`pub_events`).

    Parameters
    ----------
    node : rclpy.node.Node

    Returns
    -------
    rclpy.publisher.Publisher
        Of ``diagnostic_msgs/DiagnosticArray``.
    """
    from diagnostic_msgs.msg import DiagnosticArray

    return node.create_publisher(DiagnosticArray, DIAGNOSTICS, DIAGNOSTICS_QOS, event_callbacks=pub_events())
