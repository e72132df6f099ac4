"""Benchmarks of ``euc-ros bench``: each figure is measured beside a floor taken in the same run.

One module per benchmark; each exposes ``run(ctx: BenchContext) -> dict`` (see
:mod:`euc_ros.bench.common`). The modules are ROS-free at import time: the live benchmarks import
rclpy (and the launcher) only inside the functions that need it, and their helper processes are
:mod:`euc_ros.bench.probe` and :mod:`euc_ros.bench.relay`.

=============  ==========================================================================
module         what it measures (floor)
=============  ==========================================================================
latency        live mocap_ingest -> rider_state -> torque_estimator latency per hop and end
               to end, frames dropped (a bare rclpy relay chain, same hops and sizes)
throughput     identify and residual on a 10-minute recording, CSV and bag, in
               recording-seconds per wall-second (loading the recording alone)
growth         identify and residual on 1, 10 and 60-minute recordings: time per recorded
               minute, its growth exponent, peak memory above the process baseline per byte
               of the recording's arrays (loading the recording alone)
csv_parse      Motive CSV parse rate (numpy.loadtxt reading the same numbers)
recording      recorder messages per second into MCAP with no loss (rosbags writing the
               same messages directly)
unicycle       unicycle simulation real-time factor in process and in lockstep over topics
               (the bare RK4 physics; a bare rclpy lockstep ping-pong)
ridesim        ride simulator real-time factor, compiled and reference (the compiled
               integration of the same runs alone)
campaign       a campaign of simulated-seed tasks (ride + identify) on a local Dask cluster of 2
               worker processes, in tasks per wall-minute, its speed-up, the cluster's start-up,
               rows identical (the same tasks run serially in one process)
skeleton       live skeleton CoG (``cog_method: skeleton``) per frame at 14 bodies, compiled
               and numpy reference (the per-segment CoG of the same frames)
play           replay timing of ``euc-ros play`` per message, at rates 1 and 2 (a bare wait
               loop on the same schedule)
fuzz           NatNet packets and Motive CSV files: inputs, crashes, hangs, rejection classes
live_sweep     the whole live pipeline (with monitor and recorder) at 120/240/360/500 Hz x
               14/28/56 bodies, 60 s each: hops, end to end, CPU per node, drops (the bare
               relay chain at the same rate and body count)
soak           10 minutes at 360 Hz x 14 bodies through the whole pipeline (the same floor)
=============  ==========================================================================
"""

#: Benchmarks in the order they run (module names under euc_ros.bench).
BENCHMARKS = ("csv_parse", "throughput", "growth", "unicycle", "ridesim", "campaign", "skeleton", "recording",
              "latency", "play", "fuzz", "live_sweep", "soak")
