"""ROS-free core of euc_ros: numpy/scipy only, in layers that import downwards only.

No module below this package may import rclpy, any ``*_msgs`` package, ``euc_msgs`` or
matplotlib (enforced by ``test/unit/test_core_imports.py``).

:data:`LAYERS` is the one statement of the core's order, from the bottom up; ``test/unit/test_layers.py``
checks every import (module level and inside functions) against it. A module may import from its own
layer entry and from any entry below; the names grouped in one entry are siblings that must not import
each other (e.g. the residual analysis and the online estimators both build on identification, and
neither needs the other). Each name is a module (``errors``) or a subpackage (``mocap``) of the core.

* ``errors``: the exception hierarchy; ``memory``: giving freed memory back between large steps;
  ``robust``: numpy's median of long arrays, selected among the values near it.
  ``rotations``: quaternions and frame changes. ``yamlfile``:
  YAML with located errors. ``anthropometry``: the one anthropometric table (the rider's segments
  and pitch inertia from mass, height and sex), read by the session's default rider and ``session init``.
* ``session``: the session file (subject and vehicle of a recording), read by everything above.
* ``mocap``: motion-capture series and what is measured on them alone (rate, bridging, conventions,
  presence, live frames, the pose-noise model); ``filters``: Savitzky-Golay and low-lag derivatives.
* ``io``: files and wire formats (Motive CSV, rosbag2/MCAP, NatNet, CDR); ``model``: the EUC's
  3-DoF equations, the torques and the library of effects that extend them.
* ``states``: from poses to the model's states (geometry, skeleton fit, reconstruction, low-lag states),
  the floor under the wheel, and the model's evaluation contexts of reconstructed runs.
* ``identify``: the rider CoG height h with its interval (fit, extended model, bootstrap, SIMEX, budget;
  :func:`~euc_ros.core.identify.cog_height.identify_h`).
* ``residual``: tracing M_d1 - M_d2 to a missing effect; ``online``: the frame-by-frame estimators and
  monitors behind the nodes.
* ``ridesim``: the ride simulator (shares no code with the model, by design); ``worldsim``: a second,
  independent ride generator (its own dynamics, controllers and writer) that the analyses are tested on;
  ``unicycle``: the autonomous unicycle of the steering paper.
* ``openworld``: the open-world study (generator rides with hidden random laws and the ride simulator's
  soft-tissue artefacts, traced by the residual analysis and judged against the truth).
"""

#: The core's layers from the bottom up; each entry a tuple of sibling modules or subpackages.
LAYERS: tuple[tuple[str, ...], ...] = (
    ("errors", "memory", "robust"),
    ("rotations", "yamlfile", "anthropometry"),
    ("session",),
    ("mocap", "filters"),
    ("io", "model"),
    ("states",),
    ("identify",),
    ("residual", "online"),
    ("ridesim", "unicycle", "worldsim"),
    ("openworld",),
)
