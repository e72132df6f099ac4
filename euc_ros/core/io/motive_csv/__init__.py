"""OptiTrack Motive CSV exports: a fast, strict-where-broken, lenient-where-real reader and a writer.

The reader turns a Motive "Export Tracking Data" CSV (format 1.21, 1.22, 1.23;
docs/motive_csv.md) into a :class:`~euc_ros.core.mocap.series.MocapSeries` in the REP-103 Z-up world, SI units.
It is ROS-free and used by the mocap node and by every offline command.

Layout of a file (1.23; in 1.21/1.22 the label cells ``Type``, ``Name``, ``ID`` are empty)::

    line 1   Format Version,1.23,Take Name,...,Export Frame Rate,120.000000,...   key,value pairs
    line 2   (empty, or a row of commas)
    line 3   ,Type,Rigid Body,Rigid Body,...,Marker,...
    line 4   ,Name,E,E,...
    line 5   ,ID,1,1,...
    line 6   ,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error
    line 7   Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,
    line 8+  data rows (blank cells = untracked)

Conventions
-----------
* Columns are grouped by (Type, Name, ID) read from the header rows, never by position. Only
  ``Rigid Body`` groups are read. Skeleton bones, markers and unknown types are skipped and counted
  (``meta["skipped"]``, :func:`skipped_assets`), bones and unknown types with a warning naming them
  (markers beside rigid bodies are the usual export): euc_ros tracks the rider
  by rigid bodies at the pivots of the recording contract, and a bone's frame is not one of them. A
  file with no rigid body at all is refused by every command (:func:`require_rigid_bodies`), with
  what it holds instead and what to export.
* Time is ``t = Frame / Export Frame Rate`` [s] (docs/motive_csv.md): the ``Time (Seconds)`` column is
  rounded to whole milliseconds by some exporters and is not used.
* Y-up files (Motive's default, ``world_up="y"``): with REP-103 axes (x, y, z) the Motive axes are
  (X, Y, Z) = (x, z, -y), so a position (X, Y, Z) becomes (X, -Z, Y) and a quaternion
  (qx, qy, qz, qw) becomes (qx, -qz, qy, qw). ``world_up="z"`` leaves the axes as they are.
* Euler rotation types (``XYZ``, ``XZY``, ``YXZ``, ``YZX``, ``ZXY``, ``ZYX``; degrees) are Motive's
  *relative* (intrinsic) sequences: for ``XYZ`` the body is rotated about X, then about the new Y,
  then about the new Z, i.e. ``R = Rx(a_X) @ Ry(a_Y) @ Rz(a_Z)`` (NaturalPoint knowledge-base article
  "Changes in Motive's Reported Euler Angles", Motive >= 1.6; scipy's upper-case sequence names).
  The columns headed X, Y, Z hold the angles about X, Y and Z whatever the order. Angles are applied
  in the file's own (Motive) frame, then the axis swap above is applied to the quaternion.
* Quaternions are (x, y, z, w), body-to-world, normalised, with w >= 0.

Speed and memory: the data rows are read in chunks of about 1 MB, each converted by numpy's C float
parser (after a vectorized check of the row shapes where it fails) and turned into poses in place,
in arrays sized once by a first pass that counts the rows. The file is never held whole, nor the
matrix of all its cells: the peak memory is the result plus a few chunks. A per-cell scan only runs
on the chunk that holds an error, to name its line and column. See ``docs/motive_csv.md``.

Modules: :mod:`.header` (the header rows, :func:`read_motive_header`), :mod:`.block` (the data rows, chunk
by chunk), :mod:`.reader` (:func:`read_motive_csv`), :mod:`.writer` (:func:`write_motive_csv`).
"""
from euc_ros.core.io.motive_csv.header import (
    DEFAULT_EULER_ORDER,
    ERROR_COMPONENTS,
    EULER_ORDERS,
    LENGTH_UNITS_M,
    MARKER_TYPES,
    MAX_HEADER_LINES,
    MAX_RATE_HZ,
    MIN_RATE_HZ,
    QUATERNION,
    UP_AXIS_NOTE,
    read_motive_header,
    require_rigid_bodies,
    skipped_assets,
)
from euc_ros.core.io.motive_csv.reader import PLAUSIBLE_REACH_M, QUAT_NORM_TOLERANCE, read_motive_csv
from euc_ros.core.io.motive_csv.writer import write_motive_csv

__all__ = ["DEFAULT_EULER_ORDER", "ERROR_COMPONENTS", "EULER_ORDERS", "LENGTH_UNITS_M", "MARKER_TYPES",
           "MAX_HEADER_LINES", "MAX_RATE_HZ", "MIN_RATE_HZ", "PLAUSIBLE_REACH_M", "QUATERNION", "QUAT_NORM_TOLERANCE",
           "UP_AXIS_NOTE", "read_motive_csv", "read_motive_header", "require_rigid_bodies", "skipped_assets",
           "write_motive_csv"]
