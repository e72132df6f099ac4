"""Motive CSV reader and writer (euc_ros.core.io.motive_csv).

Hand-made files with known poses are built here as text, independently of the product's writer.
Expected rotations are built from elementary rotation matrices multiplied by hand (not scipy's Euler
code the reader uses), and the Y-up -> Z-up change of axes as a matrix similarity (not the component
swap the reader uses).

Tolerances come from the decimals of the file, which are the same on every machine: a cell written
with 9 decimals (``f9``, and the writer's default) is within 0.5e-9 of its value, so a position is
within 0.5e-9 m per axis (atol 1e-9 on round trips, 1e-8 for Euler angles in degrees whose 0.5e-9
deg is 1e-11 rad) and a rotation matrix from four such quaternion components, renormalised, within
sum_i |dR/dq_i| 0.5e-9 <= 4e-9 (atol 1e-8; 2e-9 on the quaternion itself). Time is frame / rate,
recomputed exactly (atol 1e-12 s). Cells that are exact decimals (0, 1, 0.5, 1234.5) and a reader
that only permutes, negates or scales them by a power of ten: a few ulps (atol/rtol 1e-12).
"""
# covers: euc_ros/core/mocap/series.py
# covers: euc_ros/core/io/motive_csv/reader.py
# covers: euc_ros/core/io/motive_csv/header.py
# covers: euc_ros/core/io/motive_csv/block.py
# covers: euc_ros/core/io/motive_csv/writer.py
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.io.motive_csv import read_motive_csv, read_motive_header, write_motive_csv
from euc_ros.core.mocap.conventions import infer_up_axis
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.rotations import rotation_matrices

REAL = Path(__file__).resolve().parents[4].parent / "shared" / "data" / "motive_real"
needs_real = pytest.mark.skipif(not REAL.is_dir(), reason=f"real Motive exports not available ({REAL} is absent)")

#: Z-up (REP-103) coordinates -> Motive Y-up coordinates: (X, Y, Z) = (x, z, -y) (docs/motive_csv.md).
M = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def Rx(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def Ry(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def Rz(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


ELEMENTARY = {"X": Rx, "Y": Ry, "Z": Rz}

# ----------------------------------------------------------------------------------- text builder
STANDARD_META = [("Format Version", "1.23"), ("Take Name", "hand_made"), ("Take Notes", ""),
                 ("Capture Frame Rate", "120.000000"), ("Export Frame Rate", "120.000000"),
                 ("Capture Start Time", "2024-05-02 10.15.00.000 AM"), ("Capture Start Frame", "0"),
                 ("Total Frames in Take", "3"), ("Total Exported Frames", "3"), ("Rotation Type", "Quaternion"),
                 ("Length Units", "Meters"), ("Coordinate Space", "Global")]
# 1-based columns of the values on line 1 of STANDARD_META
COL_EXPORT_RATE, COL_ROTATION_TYPE, COL_UNITS = 10, 20, 22


def meta_with(**changes):
    """STANDARD_META with values replaced (key_with_underscores=value) or removed (value None)."""
    out = []
    for k, v in STANDARD_META:
        key = k.replace(" ", "_")
        if key in changes:
            if changes[key] is None:
                continue
            v = changes[key]
        out.append((k, v))
    return out


def quote(cell: str) -> str:
    return '"' + cell.replace('"', '""') + '"' if ("," in cell or '"' in cell) else cell


def rb_columns(name, body_id="1", *, euler=False, error="Mean Marker Error"):
    rot = "XYZ" if euler else "XYZW"
    cols = [("Rigid Body", name, body_id, "Rotation", a) for a in rot]
    cols += [("Rigid Body", name, body_id, "Position", a) for a in "XYZ"]
    if error:
        cols.append(("Rigid Body", name, body_id, error, ""))
    return cols


def marker_columns(name, marker_id="M1", kind="Marker"):
    return [(kind, name, marker_id, "Position", a) for a in "XYZ"]


def motive_text(columns, rows, *, meta=None, labelled=True, time_label="Time (Seconds)", eol="\n",
                second_line="", drop_rows=()):
    """Text of a Motive export: line 1 meta, [second line], Type, Name, ID, component, axis, data."""
    meta = STANDARD_META if meta is None else meta
    lines = [",".join(f"{quote(k)},{quote(v)}" for k, v in meta)]
    if second_line is not None:
        lines.append(second_line)

    def label(s):
        return s if labelled else ""

    header = {"type": ["", label("Type")] + [quote(c[0]) for c in columns],
              "name": ["", label("Name")] + [quote(c[1]) for c in columns],
              "id": ["", label("ID")] + [quote(c[2]) for c in columns],
              "component": ["", ""] + [quote(c[3]) for c in columns]}
    for key in ("type", "name", "id", "component"):
        if key not in drop_rows:
            lines.append(",".join(header[key]))
    lines.append(",".join(["Frame", time_label] + [c[4] for c in columns]))
    lines.extend(",".join(str(c) for c in r) for r in rows)
    return eol.join(lines) + eol


def put(tmp_path: Path, text: str | bytes, name: str = "take.csv") -> Path:
    p = tmp_path / name
    p.write_bytes(text.encode("utf-8") if isinstance(text, str) else text)
    return p


def f9(x) -> str:
    return f"{x:.9f}"


def pose_cells(R_file, p_file, err=0.0001, q_sign=1.0):
    """Quaternion (x, y, z, w) + position + error cells of a pose given in the file's frame."""
    q = q_sign * Rotation.from_matrix(R_file).as_quat()
    return [f9(v) for v in q] + [f9(v) for v in p_file] + [f9(err)]


def row(frame, cells, rate=120.0):
    return [str(frame), f"{frame / rate:.6f}"] + list(cells)


def simple_rows(n=3):
    """n frames of body E at slowly moving known poses (file frame = Y-up)."""
    out = []
    for k in range(n):
        out.append(row(k, pose_cells(Ry(0.1 * k), [0.1 * k, 0.9, -0.2 * k])))
    return out


# ---------------------------------------------------------------------------------------- frames
def test_yaw_left_in_y_up_file_is_yaw_left_in_z_up(tmp_path):
    # A body at Z-up position (1, 2, 0.5), yawed +90 deg (facing world +y). In Motive's Y-up world the
    # position is (X, Y, Z) = (x, z, -y) = (1, 0.5, -2) and the yaw is +90 deg about Motive +Y.
    s45 = math.sqrt(0.5)
    cells = [f9(0), f9(s45), f9(0), f9(s45), "1.0", "0.5", "-2.0", "0.0002"]
    p = put(tmp_path, motive_text(rb_columns("E"), [row(0, cells)]))
    s = read_motive_csv(p)
    np.testing.assert_allclose(s.position[0, 0], [1.0, 2.0, 0.5], atol=1e-12)
    R = rotation_matrices(s.quat[0, 0])   # two inexact 9-decimal cells: <= 2 * 2 * 0.5e-9 per entry
    np.testing.assert_allclose(R[:, 0], [0, 1, 0], atol=2e-9)  # body forward axis -> world +y
    np.testing.assert_allclose(R[:, 1], [-1, 0, 0], atol=2e-9)  # body left axis -> world -x
    np.testing.assert_allclose(R[:, 2], [0, 0, 1], atol=2e-9)  # still upright
    assert s.mean_marker_error[0, 0] == pytest.approx(0.0002)


def test_pitch_forward_in_y_up_file(tmp_path):
    # Pitching forward by 20 deg (REP-103: positive rotation about body/world +y) tips the body's z axis
    # towards +x. World +y is Motive -Z, so in the file it is a rotation of -20 deg about Motive Z.
    a = math.radians(20)
    cells = [f9(0), f9(0), f9(-math.sin(a / 2)), f9(math.cos(a / 2)), "0", "1", "0", ""]
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), [row(0, cells)])))
    R = rotation_matrices(s.quat[0, 0])   # two inexact 9-decimal cells: <= 2 * 2 * 0.5e-9 per entry
    np.testing.assert_allclose(R[:, 2], [math.sin(a), 0, math.cos(a)], atol=2e-9)
    np.testing.assert_allclose(R[:, 0], [math.cos(a), 0, -math.sin(a)], atol=2e-9)
    np.testing.assert_allclose(s.position[0, 0], [0, 0, 1], atol=1e-12)
    assert np.isnan(s.mean_marker_error[0, 0]) and s.tracked[0, 0]  # blank quality cell alone is no gap


def test_random_poses_y_up_to_z_up_by_similarity_transform(tmp_path):
    rng = np.random.default_rng(8)
    R_z = Rotation.random(20, random_state=rng).as_matrix()        # truth, Z-up world
    p_z = rng.uniform(-3, 3, size=(20, 3))
    rows = []
    for k in range(20):
        # Alternate the quaternion sign in the file: the sign of a quaternion is arbitrary.
        rows.append(row(k, pose_cells(M @ R_z[k] @ M.T, M @ p_z[k], q_sign=(-1) ** k)))
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows)))
    np.testing.assert_allclose(s.position[0], p_z, atol=1e-8)
    np.testing.assert_allclose(rotation_matrices(s.quat[0]), R_z, atol=1e-8)
    assert np.all(s.quat[0, :, 3] >= 0)
    np.testing.assert_allclose(np.linalg.norm(s.quat[0], axis=1), 1.0, atol=1e-12)


def test_world_up_z_means_no_axis_swap(tmp_path):
    rng = np.random.default_rng(3)
    R = Rotation.random(5, random_state=rng).as_matrix()
    p = rng.normal(size=(5, 3))
    rows = [row(k, pose_cells(R[k], p[k])) for k in range(5)]
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows)), world_up="z")
    np.testing.assert_allclose(s.position[0], p, atol=1e-8)
    np.testing.assert_allclose(rotation_matrices(s.quat[0]), R, atol=1e-8)
    assert s.meta["world_up"] == "z"


@pytest.mark.parametrize("order", ["XYZ", "XZY", "YXZ", "YZX", "ZXY", "ZYX"])
def test_euler_rotation_types(tmp_path, order):
    rng = np.random.default_rng(abs(hash(order)) % 2**32)
    angles = rng.uniform(-170, 170, size=(6, 3))  # columns: about X, about Y, about Z [deg]
    angles[:, "XYZ".index(order[1])] = rng.uniform(-80, 80, size=6)  # middle angle away from gimbal lock
    p_file = rng.normal(size=(6, 3))
    rows = [row(k, [f9(a) for a in angles[k]] + [f9(v) for v in p_file[k]] + ["0.0001"]) for k in range(6)]
    text = motive_text(rb_columns("E", euler=True), rows, meta=meta_with(Rotation_Type=order))
    s = read_motive_csv(put(tmp_path, text))
    assert s.meta["rotation_type"] == order
    for k in range(6):
        a = dict(zip("XYZ", np.radians(angles[k])))
        # Motive's relative (intrinsic) order: about the first axis, then the new second, then the new third.
        first, second, third = (ELEMENTARY[ax](a[ax]) for ax in order)
        R_file = first @ second @ third
        np.testing.assert_allclose(rotation_matrices(s.quat[0, k]), M.T @ R_file @ M, atol=1e-8)
        np.testing.assert_allclose(s.position[0, k], M.T @ p_file[k], atol=1e-8)
    assert np.all(s.quat[0, :, 3] >= 0)


def test_euler_is_intrinsic_not_extrinsic(tmp_path):
    # 90 deg about X then 90 deg about the NEW Y: distinguishable from the extrinsic reading.
    rows = [row(0, ["90", "90", "0", "0", "0", "0", ""])]
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E", euler=True), rows,
                                                   meta=meta_with(Rotation_Type="XYZ"))), world_up="z")
    R = rotation_matrices(s.quat[0, 0])
    np.testing.assert_allclose(R, Rx(math.pi / 2) @ Ry(math.pi / 2), atol=1e-9)
    assert not np.allclose(R, Ry(math.pi / 2) @ Rx(math.pi / 2), atol=1e-3)


@pytest.mark.parametrize("units,scale", [("Millimeters", 1e-3), ("Centimeters", 1e-2), ("Meters", 1.0)])
def test_length_units_scale_positions_and_marker_error(tmp_path, units, scale):
    p_file = np.array([1234.5, 876.0, -2000.0])
    cells = ["0", "0", "0", "1"] + [f9(v) for v in p_file] + ["0.5"]
    text = motive_text(rb_columns("E"), [row(0, cells)], meta=meta_with(Length_Units=units))
    s = read_motive_csv(put(tmp_path, text))
    np.testing.assert_allclose(s.position[0, 0], scale * np.array([1234.5, 2000.0, 876.0]), rtol=1e-12)
    assert s.mean_marker_error[0, 0] == pytest.approx(0.5 * scale)
    assert s.meta["length_units"] == units


def test_non_unit_zero_and_huge_quaternions(tmp_path):
    rows = [row(0, ["0", "0", "0", "2", "0", "1", "0", ""]),          # norm 2: normalised, warned
            row(1, ["0", "0", "0", "0", "0", "1", "0", ""]),          # zero: not a rotation -> gap
            row(2, ["0", "1e200", "0", "1e200", "0", "1", "0", ""])]  # would overflow a naive norm
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows)))
    np.testing.assert_array_equal(s.tracked[0], [True, False, True])
    np.testing.assert_allclose(s.quat[0, 0], [0, 0, 0, 1])
    np.testing.assert_allclose(s.quat[0, 2], [0, 0, math.sqrt(0.5), math.sqrt(0.5)])  # Y-up y -> Z-up z
    assert np.isnan(s.quat[0, 1]).all() and np.isnan(s.position[0, 1]).all()
    assert any("not unit" in w for w in s.meta["warnings"])


# -------------------------------------------------------------------------------- gaps and frames
def test_blank_and_partly_blank_groups_are_gaps_never_zeros(tmp_path):
    cols = rb_columns("E") + marker_columns("E:Marker1")
    good = pose_cells(np.eye(3), [0.1, 0.9, 0.2])
    rows = [row(0, good + ["1", "2", "3"]),
            row(1, [""] * 8 + ["1", "2", "3"]),                      # whole group blank, markers still seen
            row(2, good[:5] + [""] + good[6:] + ["1", "2", "3"]),     # Position Y blank only
            row(3, good + ["", "", ""])]                             # marker blank: body still tracked
    s = read_motive_csv(put(tmp_path, motive_text(cols, rows)))
    np.testing.assert_array_equal(s.tracked[0], [True, False, False, True])
    assert np.isnan(s.position[0, 1:3]).all() and np.isnan(s.quat[0, 1:3]).all()
    assert np.isnan(s.mean_marker_error[0, 1:3]).all()
    assert np.isfinite(s.position[0, [0, 3]]).all()
    assert s.meta["occlusions"] == {"E": 2}
    assert s.meta["n_partial_blank"] == {"E": 1}


def test_time_is_frame_over_export_rate_and_gaps_counted(tmp_path):
    frames = [10, 11, 12, 15, 16, 20]
    rows = []
    for f in frames:
        r = row(f, pose_cells(np.eye(3), [0, 1, 0]))
        r[1] = f"{round(f / 120, 3):.6f}"  # Time column rounded to whole ms, as some exporters do
        rows.append(r)
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows)))
    np.testing.assert_array_equal(s.frame, frames)
    assert s.frame.dtype == np.int64
    np.testing.assert_allclose(s.t, np.array(frames) / 120.0, rtol=0, atol=1e-15)
    assert s.meta["n_dropped"] == 2 + 3
    assert s.meta["n_duplicates_dropped"] == 0
    assert s.rate_hz == 120.0


def test_duplicate_and_out_of_order_frames_dropped_keeping_first(tmp_path):
    frames = [0, 1, 1, 2, 1, 3]
    rows = [row(f, pose_cells(np.eye(3), [float(k), 1, 0])) for k, f in enumerate(frames)]
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows)))
    np.testing.assert_array_equal(s.frame, [0, 1, 2, 3])
    np.testing.assert_allclose(s.position[0, :, 0], [0.0, 1.0, 3.0, 5.0])  # first frame 1 kept
    assert s.meta["n_duplicates_dropped"] == 2
    assert s.meta["n_dropped"] == 0


def test_crlf_equals_lf(tmp_path):
    cols = rb_columns("E") + marker_columns("m")
    rows = [r + ["1", "2", "3"] for r in simple_rows(4)]
    rows[2][2:10] = [""] * 8
    a = read_motive_csv(put(tmp_path, motive_text(cols, rows), "lf.csv"))
    b = read_motive_csv(put(tmp_path, motive_text(cols, rows, eol="\r\n"), "crlf.csv"))
    for name in ("t", "frame", "position", "quat", "tracked", "mean_marker_error"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    assert b.meta["start_time"] == "2024-05-02 10.15.00.000 AM"


def test_quoted_names_with_commas_and_duplicate_names_across_types(tmp_path):
    cols = (marker_columns("E", "E") + rb_columns("Rider, left hand", '"7"')
            + marker_columns("E", "9", "Rigid Body Marker")
            + rb_columns("E", "2"))
    hand = pose_cells(np.eye(3), [1, 2, 3])
    e = pose_cells(np.eye(3), [4, 5, 6])
    rows = [row(0, ["9", "9", "9"] + hand + ["8", "8", "8"] + e)]
    s = read_motive_csv(put(tmp_path, motive_text(cols, rows)))
    assert s.bodies == ["Rider, left hand", "E"]
    np.testing.assert_allclose(s.position[:, 0], [[1, -3, 2], [4, -6, 5]])


def test_unknown_types_and_components_are_skipped(tmp_path):
    cols = ([("Bone", "Skel_Hip", "5", "Rotation", a) for a in "XYZW"] + [("Bone", "Skel_Hip", "5", "Position", a)
                                                                          for a in "XYZ"]
            + rb_columns("E") + [("Rigid Body", "E", "1", "Marker Quality", ""),
                                 ("Rigid Body", "E", "1", "Velocity", "X"), ("Force Plate", "FP", "3", "Force", "X")])
    rows = [row(0, ["0", "0", "0", "1", "7", "7", "7"] + pose_cells(np.eye(3), [1, 2, 3]) + ["0.9", "5", "100"])]
    s = read_motive_csv(put(tmp_path, motive_text(cols, rows)))
    assert s.bodies == ["E"]
    np.testing.assert_allclose(s.position[0, 0], [1, -3, 2])


def test_v122_header_empty_labels_time_error_per_marker_missing_keys(tmp_path):
    meta = [("Format Version", "1.22"), ("Take Name", "old"), ("Capture Frame Rate", "240"),
            ("Export Frame Rate", "60"), ("Capture Start Time", "2020-06-16 07.51.41.245 PM"),
            ("Total Frames in Take", "904"), ("Total Exported Frames", "2")] + [("", "")] * 5
    cols = rb_columns("RigidBody 01", error="Error Per Marker")
    rows = [row(0, pose_cells(np.eye(3), [1, 2, 3], err=0.25), 60), row(1, pose_cells(np.eye(3), [1, 2, 4]), 60)]
    text = motive_text(cols, rows, meta=meta, labelled=False, time_label="Time", second_line="," * 12)
    s = read_motive_csv(put(tmp_path, text))
    assert s.bodies == ["RigidBody 01"]
    np.testing.assert_allclose(s.t, [0, 1 / 60])
    assert s.meta["format_version"] == "1.22"
    assert s.meta["capture_rate_hz"] == 240.0 and s.meta["rate_hz"] == 60.0
    assert s.meta["length_units"] == "Meters" and s.meta["rotation_type"] == "Quaternion"
    assert s.meta["coordinate_space"] is None
    assert any("assumed Meters" in w for w in s.meta["warnings"])
    assert any("Quaternion" in w for w in s.meta["warnings"])
    assert s.mean_marker_error[0, 0] == pytest.approx(0.25)


def test_v121_without_export_rate_uses_capture_rate(tmp_path):
    meta = [("Format Version", "1.21"), ("Take Name", "older"), ("Capture Frame Rate", "100")]
    rows = [row(f, pose_cells(np.eye(3), [0, 1, 0]), 100) for f in (0, 1, 2)]
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows, meta=meta, labelled=False, time_label="Time")))
    np.testing.assert_allclose(s.t, [0, 0.01, 0.02])
    assert s.meta["rate_source"] == "Capture Frame Rate"
    assert any("Export Frame Rate" in w for w in s.meta["warnings"])


def test_without_any_rate_the_time_column_gives_it(tmp_path):
    meta = [("Format Version", "1.23"), ("Take Name", "x")]
    rows = [row(f, pose_cells(np.eye(3), [0, 1, 0]), 250) for f in (0, 1, 2, 3)]
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows, meta=meta)))
    assert s.rate_hz == pytest.approx(250.0, rel=1e-5)


def test_body_selection_and_order(tmp_path):
    cols = rb_columns("A", "1") + rb_columns("B", "2") + rb_columns("C", "3")
    rows = [row(0, sum((pose_cells(np.eye(3), [x, 0, 0]) for x in (1, 2, 3)), []))]
    p = put(tmp_path, motive_text(cols, rows))
    s = read_motive_csv(p, bodies=["C", "A"])
    assert s.bodies == ["C", "A"]
    np.testing.assert_allclose(s.position[:, 0, 0], [3, 1])
    assert set(s.meta["occlusions"]) == {"C", "A"}
    with pytest.raises(InputError, match="rigid body 'D' not in the file.*has: A, B, C"):
        read_motive_csv(p, bodies=["A", "D"])


def test_header_only_and_no_data_columns(tmp_path):
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), []), "a.csv"))
    assert s.bodies == ["E"] and s.n_frames == 0 and s.position.shape == (1, 0, 3)
    s = read_motive_csv(put(tmp_path, motive_text([], [["0", "0.000000"], ["1", "0.008000"]]), "b.csv"))
    assert s.bodies == [] and s.n_frames == 2 and s.position.shape == (0, 2, 3)
    np.testing.assert_allclose(s.t, [0, 1 / 120])


def test_trailing_empty_cells_in_data_rows_are_accepted(tmp_path):
    rows = [r + ["", ""] for r in simple_rows(3)]
    s = read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows)))
    assert s.n_frames == 3 and s.tracked.all()


def test_unterminated_complete_last_line_is_accepted_with_a_warning(tmp_path):
    text = motive_text(rb_columns("E"), simple_rows(3)).rstrip("\n")
    s = read_motive_csv(put(tmp_path, text))
    assert s.n_frames == 3
    assert any("no line end" in w for w in s.meta["warnings"])


def test_read_motive_header_is_cheap_and_consistent(tmp_path):
    cols = rb_columns("A", "1") + marker_columns("A:M") + rb_columns("B", "2")
    rows = [row(0, pose_cells(np.eye(3), [0, 1, 0]) + ["1", "1", "1"] + pose_cells(np.eye(3), [0, 1, 0]))]
    text = motive_text(cols, rows)
    p = put(tmp_path, text + "garbage that the header reader never looks at\n")
    h = read_motive_header(p)
    assert h["bodies"] == ["A", "B"]
    assert h["rate_hz"] == 120.0 and h["rotation_type"] == "Quaternion" and h["length_units"] == "Meters"
    assert h["n_columns"] == 2 + 8 + 3 + 8
    with pytest.raises(InputError):
        read_motive_csv(p)


# ---------------------------------------------------------------------------------------- errors
def test_non_numeric_cell_names_line_column_and_header(tmp_path):
    rows = simple_rows(3)
    rows[1][7] = "abc"  # second data row (line 9), cell index 7 -> column 8 = E Position Y
    with pytest.raises(InputError, match=r"take\.csv, line 9, column 8: non-numeric cell \('E Position Y'\): 'abc'"):
        read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows)))


def test_non_numeric_cell_in_an_ignored_marker_column_is_still_an_error(tmp_path):
    rows = [r + ["1", "2", "3"] for r in simple_rows(3)]
    rows[2][11] = "1.2.3"
    with pytest.raises(InputError, match=r"line 10, column 12: non-numeric cell \('m Position Y'\)"):
        read_motive_csv(put(tmp_path, motive_text(rb_columns("E") + marker_columns("m"), rows)))


def test_error_deep_in_a_long_file_is_located(tmp_path):
    rows = [row(k, pose_cells(np.eye(3), [0, 1, 0])) for k in range(5000)]
    rows[4321][4] = "1e"  # data row 4321 -> line 8 + 4321
    with pytest.raises(InputError, match=rf"line {8 + 4321}, column 5: non-numeric cell \('E Rotation Z'\)"):
        read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows)))


@pytest.mark.parametrize("labelled", [True, False])
def test_missing_name_row(tmp_path, labelled):
    text = motive_text(rb_columns("E"), simple_rows(), drop_rows=("name",), labelled=labelled,
                       second_line="" if labelled else ",,,,")
    pattern = r"line 4, column 2: missing header row 'Name'" if labelled else \
        r"line 2, column 3: missing header rows: the type row is empty"
    with pytest.raises(InputError, match=pattern):
        read_motive_csv(put(tmp_path, text))


def test_missing_header_rows_without_second_line(tmp_path):
    text = motive_text(rb_columns("E"), simple_rows(), drop_rows=("id",), labelled=False, second_line=None)
    with pytest.raises(InputError, match=r"line 5, column 1: missing header rows"):
        read_motive_csv(put(tmp_path, text))


def test_file_cut_inside_the_header(tmp_path):
    text = "\n".join(motive_text(rb_columns("E"), simple_rows()).split("\n")[:4]) + "\n"
    with pytest.raises(InputError, match=r"line 4, column 1: missing header rows: no 'Frame"):
        read_motive_csv(put(tmp_path, text))


def test_truncated_last_line(tmp_path):
    text = motive_text(rb_columns("E"), simple_rows(3))
    cut = text[: text.rstrip("\n").rfind(",", 0, len(text) - 30)]  # last line loses its last cells
    n_cells = cut.split("\n")[-1].count(",") + 1
    with pytest.raises(InputError, match=rf"line 10, column {n_cells + 1}: truncated last line: {n_cells} of 10"):
        read_motive_csv(put(tmp_path, cut))


def test_truncated_middle_line(tmp_path):
    rows = simple_rows(3)
    rows[1] = rows[1][:5]
    with pytest.raises(InputError, match=r"line 9, column 6: truncated line: 5 of 10 cells.*'E Rotation W'"):
        read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows)))


def test_unknown_rotation_type(tmp_path):
    text = motive_text(rb_columns("E"), simple_rows(), meta=meta_with(Rotation_Type="Matrix"))
    with pytest.raises(InputError, match=rf"line 1, column {COL_ROTATION_TYPE}, key 'Rotation Type': "
                                         r"unknown Rotation Type 'Matrix'"):
        read_motive_csv(put(tmp_path, text))


def test_unknown_length_units(tmp_path):
    text = motive_text(rb_columns("E"), simple_rows(), meta=meta_with(Length_Units="Furlongs"))
    with pytest.raises(InputError, match=rf"line 1, column {COL_UNITS}, key 'Length Units': unknown Length Units"):
        read_motive_csv(put(tmp_path, text))


def test_bad_export_rate(tmp_path):
    text = motive_text(rb_columns("E"), simple_rows(), meta=meta_with(Export_Frame_Rate="fast"))
    with pytest.raises(InputError, match=rf"line 1, column {COL_EXPORT_RATE}, key 'Export Frame Rate'"):
        read_motive_csv(put(tmp_path, text))


@pytest.mark.parametrize("cell", ["1.5", "", "x", "nan"])
def test_frame_not_integer(tmp_path, cell):
    rows = simple_rows(3)
    rows[1][0] = cell
    match = r"line 9, column 1: Frame column is not an integer" if cell != "x" else r"line 9, column 1: non-numeric"
    with pytest.raises(InputError, match=match):
        read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows)))


def test_not_a_motive_file_and_empty_file(tmp_path):
    with pytest.raises(InputError, match=r"line 1, column 1: not a Motive CSV export"):
        read_motive_csv(put(tmp_path, "a,b,c\n1,2,3\n", "x.csv"))
    with pytest.raises(InputError, match=r"empty file"):
        read_motive_csv(put(tmp_path, "", "y.csv"))
    with pytest.raises(InputError, match=r"no such file"):
        read_motive_csv(tmp_path / "missing.csv")


def test_rigid_body_without_position_column(tmp_path):
    cols = [c for c in rb_columns("E") if (c[3], c[4]) != ("Position", "Z")]
    rows = [r[:8] + r[9:] for r in simple_rows()]
    with pytest.raises(InputError, match=r"line 7, column 3: rigid body 'E' has no 'Position Z' column"):
        read_motive_csv(put(tmp_path, motive_text(cols, rows)))


def test_rotation_type_disagrees_with_columns(tmp_path):
    with pytest.raises(InputError, match=r"line 7, column 3: Rotation Type XYZ needs rotation columns X, Y, Z"):
        read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), simple_rows(), meta=meta_with(Rotation_Type="XYZ")),
                            "a.csv"))
    rows = [r[:5] + r[6:] for r in simple_rows()]
    pattern = r"line 7, column 3: Rotation Type Quaternion needs rotation columns X, Y, Z, W"
    with pytest.raises(InputError, match=pattern):
        read_motive_csv(put(tmp_path, motive_text(rb_columns("E", euler=True), rows), "b.csv"))


def test_duplicate_column_and_duplicate_body_names(tmp_path):
    cols = rb_columns("E") + [("Rigid Body", "E", "1", "Position", "X")]
    rows = [r + ["1"] for r in simple_rows()]
    with pytest.raises(InputError, match=r"line 7, column 11: duplicate column 'E Position X' \(also column 7\)"):
        read_motive_csv(put(tmp_path, motive_text(cols, rows), "a.csv"))
    cols = rb_columns("E", "1") + rb_columns("E", "2")
    rows = [r + r[2:] for r in simple_rows()]
    with pytest.raises(InputError, match=r"line 4, column 11: two rigid bodies are named 'E'"):
        read_motive_csv(put(tmp_path, motive_text(cols, rows), "b.csv"))


def test_cell_beyond_the_header_and_blank_line(tmp_path):
    rows = simple_rows(3)
    rows[0] = rows[0] + ["", "5"]
    with pytest.raises(InputError, match=r"line 8, column 12: cell beyond the 10 columns"):
        read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), rows), "a.csv"))
    text = motive_text(rb_columns("E"), simple_rows(3)).replace("\n1,", "\n\n1,")
    with pytest.raises(InputError, match=r"line 9, column 1: blank line"):
        read_motive_csv(put(tmp_path, text, "b.csv"))


def test_time_column_missing_and_stray_header_line(tmp_path):
    text = motive_text(rb_columns("E"), simple_rows(), time_label="Seconds")
    with pytest.raises(InputError, match=r"line 7, column 2: the second column must be the time column"):
        read_motive_csv(put(tmp_path, text, "a.csv"))
    text = motive_text(rb_columns("E"), simple_rows(), second_line="Take notes here")
    with pytest.raises(InputError, match=r"line 2, column 1: unexpected header line"):
        read_motive_csv(put(tmp_path, text, "b.csv"))


def test_world_up_must_be_y_or_z(tmp_path):
    with pytest.raises(ConfigError, match="world_up"):
        read_motive_csv(put(tmp_path, motive_text(rb_columns("E"), simple_rows())), world_up="x")


# ------------------------------------------------------------------------------------------ writer
def random_series(rng, b=3, n=60, name="ride_01"):
    frames = np.cumsum(rng.integers(1, 3, size=n)) + 100  # gaps in the numbering
    q = Rotation.random(b * n, random_state=rng).as_quat().reshape(b, n, 4)
    q[..., 3] = np.abs(q[..., 3])
    trk = rng.random((b, n)) > 0.1
    pos = rng.uniform(-4, 4, size=(b, n, 3))
    err = rng.uniform(0, 1e-3, size=(b, n))
    pos[~trk] = np.nan
    q[~trk] = np.nan
    err[~trk] = np.nan
    return MocapSeries(frames / 120.0, frames.astype(np.int64), ["E", "H", "Left, hand"], pos, q, trk, err, name,
                       {"rate_hz": 120.0, "start_time": "2024-05-02 10.15.00.000 AM"})


@pytest.mark.parametrize("world_up", ["y", "z"])
def test_write_read_round_trip(tmp_path, world_up):
    s = random_series(np.random.default_rng(11))
    p = write_motive_csv(s, tmp_path / "out.csv", world_up=world_up)
    r = read_motive_csv(p, world_up=world_up)
    assert r.bodies == s.bodies and r.name == "ride_01"
    np.testing.assert_array_equal(r.frame, s.frame)
    np.testing.assert_allclose(r.t, s.t, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(r.tracked, s.tracked)
    np.testing.assert_allclose(r.position, s.position, atol=1e-9)
    np.testing.assert_allclose(r.quat, s.quat, atol=2e-9)
    np.testing.assert_allclose(r.mean_marker_error, s.mean_marker_error, atol=1e-9)
    assert r.meta["start_time"] == s.meta["start_time"] and r.meta["format_version"] == "1.23"
    assert r.meta["occlusions"] == {b: int((~s.tracked[k]).sum()) for k, b in enumerate(s.bodies)}


def test_written_file_follows_the_spec_layout_and_motive_axes(tmp_path):
    s = random_series(np.random.default_rng(5), n=4)
    p = write_motive_csv(s, tmp_path / "out.csv", take_name="decel_01")
    lines = p.read_text().split("\n")
    assert lines[0].startswith("Format Version,1.23,Take Name,decel_01,")
    assert "Rotation Type,Quaternion,Length Units,Meters" in lines[0]
    assert lines[1] == ""
    assert lines[2].startswith(",Type,Rigid Body,") and lines[3].startswith(",Name,E,E,")
    assert lines[4].startswith(",ID,1,") and lines[5].startswith(",,Rotation,Rotation,Rotation,Rotation,Position,")
    assert lines[6].startswith("Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,,X,")
    rows = list(csv.reader(lines[7:11]))
    k = int(np.flatnonzero(s.tracked[0])[0])
    cells = np.array(rows[k][6:9], float)  # body E position in the file: Motive Y-up axes
    np.testing.assert_allclose(cells, M @ s.position[0, k], atol=1e-9)
    untracked = np.argwhere(~s.tracked)
    if untracked.size:
        bi, fi = untracked[0]
        assert rows[fi][2 + 8 * bi: 10 + 8 * bi] == [""] * 8


def test_writer_is_atomic(tmp_path):
    target = tmp_path / "keep.csv"
    target.write_text("previous content\n")
    s = random_series(np.random.default_rng(2))
    s.bodies = ["E", "E", "H"]
    with pytest.raises(InputError, match="unique"):
        write_motive_csv(s, target)
    assert target.read_text() == "previous content\n"
    assert sorted(x.name for x in tmp_path.iterdir()) == ["keep.csv"]


# ------------------------------------------------------------------------------------- real files
@needs_real
@pytest.mark.shared
def test_real_grvc_occlusion_crlf_quoted():
    path = REAL / "grvc_1rb_120hz_m_quality_occlusion_v1.23.csv"
    s = read_motive_csv(path)
    assert s.bodies == ["ernesto_body"] and s.n_frames == 499
    assert s.meta["occlusions"] == {"ernesto_body": 1}
    assert not s.tracked[0, 4] and np.isnan(s.position[0, 4]).all() and s.tracked[0, :4].all()
    np.testing.assert_allclose(s.t, np.arange(499) / 120.0)
    # First row, read independently with the csv module: Rotation X..W cols 3-6, Position cols 7-9, error col 10
    with open(path, newline="") as fh:
        first = list(csv.reader(fh))[7]
    q_file = np.array(first[2:6], float)
    p_file = np.array(first[6:9], float)
    R_file = Rotation.from_quat(q_file).as_matrix()
    np.testing.assert_allclose(s.position[0, 0], M.T @ p_file, atol=1e-12)
    np.testing.assert_allclose(rotation_matrices(s.quat[0, 0]), M.T @ R_file @ M, atol=1e-5)
    assert s.mean_marker_error[0, 0] == pytest.approx(float(first[9]))
    assert infer_up_axis(s)["inferred"] == "y"


@needs_real
@pytest.mark.shared
def test_real_rbm_euler_v122_downsampled():
    path = REAL / "rbm_2rb_240to60hz_euler_v1.22.csv"
    s = read_motive_csv(path)
    assert s.bodies == ["RigidBody 01", "RigidBody 02"] and s.n_frames == 227
    assert s.meta["rate_hz"] == 60.0 and s.meta["capture_rate_hz"] == 240.0
    np.testing.assert_allclose(s.t[:3], [0, 1 / 60, 2 / 60])
    assert s.meta["rotation_type"] == "XYZ" and s.meta["length_units"] == "Meters"
    assert any("assumed Meters" in w for w in s.meta["warnings"])
    assert any("centimetres" in w for w in s.meta["warnings"])  # positions ~155 "m" flagged
    with open(path, newline="") as fh:
        first = list(csv.reader(fh))[7]
    ax, ay, az = np.radians(np.array(first[2:5], float))
    R_file = Rx(ax) @ Ry(ay) @ Rz(az)
    np.testing.assert_allclose(rotation_matrices(s.quat[0, 0]), M.T @ R_file @ M, atol=1e-9)
    np.testing.assert_allclose(s.position[0, 0], M.T @ np.array(first[5:8], float), atol=1e-9)
    assert s.tracked.all()


@needs_real
@pytest.mark.shared
@pytest.mark.parametrize("name", ["ha5dzs_markers_only_360hz_mm_v1.23.csv", "ha5dzs_empty_no_assets_360hz_v1.23.csv"])
def test_real_ha5dzs_without_rigid_bodies(name):
    s = read_motive_csv(REAL / name)
    assert s.bodies == [] and s.n_frames == 1353 and s.position.shape == (0, 1353, 3)
    assert s.meta["length_units"] == "Millimeters" and s.meta["start_time"].endswith("DU.")
    assert s.t[3] == pytest.approx(3 / 360)  # not the file's 0.008000 (rounded to whole ms)
    assert read_motive_header(REAL / name)["bodies"] == []


# -------------------------------------------------------------------------------------------- fuzz
_BASE = motive_text(rb_columns("E") + marker_columns("E"),
                    [r + ["1", "2", "3"] for r in simple_rows(3)] + [row(3, [""] * 8 + ["1", "", "3"])])
_ALPHABET = ',\n\r"-.0123456789eEnaif XYZW\tTypeNameIDFrameRigidBodyQuaternion\x00é'


def _check_series(s: MocapSeries) -> None:
    b, n = len(s.bodies), s.n_frames
    assert s.position.shape == (b, n, 3) and s.quat.shape == (b, n, 4) and s.tracked.shape == (b, n)
    trk = s.tracked
    assert np.isfinite(s.position[trk]).all() and np.isfinite(s.quat[trk]).all()
    assert np.isnan(s.position[~trk]).all() and np.isnan(s.quat[~trk]).all()
    if trk.any():
        np.testing.assert_allclose(np.linalg.norm(s.quat[trk], axis=1), 1.0, atol=1e-9)
        assert (s.quat[trk][:, 3] >= 0).all()
    assert np.all(np.diff(s.frame) > 0)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(ops=st.lists(st.tuples(st.sampled_from(["insert", "delete", "replace", "dup_line", "drop_line", "cut"]),
                              st.integers(0, len(_BASE)), st.integers(1, 40), st.text(_ALPHABET, max_size=6)),
                    min_size=1, max_size=5))
def test_fuzz_mutated_text_returns_or_raises_input_error(tmp_path, ops):
    text = _BASE
    for op, pos, length, chunk in ops:
        pos = min(pos, len(text))
        lines = text.split("\n")
        k = min(pos // 40, len(lines) - 1)
        if op == "insert":
            text = text[:pos] + chunk + text[pos:]
        elif op == "delete":
            text = text[:pos] + text[pos + length:]
        elif op == "replace":
            text = text[:pos] + chunk + text[pos + len(chunk):]
        elif op == "dup_line":
            text = "\n".join(lines[:k + 1] + lines[k:])
        elif op == "drop_line":
            text = "\n".join(lines[:k] + lines[k + 1:])
        else:
            text = text[:pos]
    p = put(tmp_path, text, "fuzz.csv")
    try:
        s = read_motive_csv(p)
    except InputError:
        return
    _check_series(s)


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(pos=st.integers(0, len(_BASE)), junk=st.binary(min_size=1, max_size=8))
def test_fuzz_binary_junk(tmp_path, pos, junk):
    raw = _BASE.encode()
    p = put(tmp_path, raw[:pos] + junk + raw[pos:], "junk.csv")
    try:
        _check_series(read_motive_csv(p))
    except InputError:
        pass


# ------------------------------------------------------------------------------ skeletons, markers only
BONES = ("Hip", "Ab", "Chest", "Neck", "Head", "LShoulder", "LUArm", "LFArm", "LHand", "RShoulder", "RUArm",
         "RFArm", "RHand")


def _bone_columns(name):
    cols = [("Bone", f"Skeleton_001:{name}", "2", "Rotation", a) for a in "XYZW"]
    return cols + [("Bone", f"Skeleton_001:{name}", "2", "Position", a) for a in "XYZ"]


def _skeleton_file(tmp_path, with_euc=True):
    cols = (rb_columns("E") if with_euc else []) + sum((_bone_columns(b) for b in BONES), [])
    bone_cells = pose_cells(np.eye(3), [0.0, 1.0, 0.0])[:7] * len(BONES)
    rows = [row(k, ((pose_cells(np.eye(3), [0.0, 0.9, 0.0]) if with_euc else []) + bone_cells)) for k in range(3)]
    path = tmp_path / ("skeleton_e.csv" if with_euc else "skeleton.csv")
    path.write_text(motive_text(cols, rows))
    return path


def test_skeleton_bones_are_counted_and_named_not_silently_dropped(tmp_path):
    s = read_motive_csv(_skeleton_file(tmp_path))
    assert s.bodies == ["E"]
    assert s.meta["skipped"]["Bone"] == [f"Skeleton_001:{b}" for b in BONES]
    warn = [w for w in s.meta["warnings"] if "not read" in w]
    assert len(warn) == 1 and "13 Bone" in warn[0] and "Skeleton_001:Hip" in warn[0]
    assert read_motive_header(_skeleton_file(tmp_path))["skipped"]["Bone"][0] == "Skeleton_001:Hip"


def test_markers_beside_rigid_bodies_are_counted_without_a_warning(tmp_path):
    path = tmp_path / "m.csv"
    path.write_text(motive_text(rb_columns("E") + marker_columns("E:Marker1", kind="Rigid Body Marker"),
                                [r + ["1", "2", "3"] for r in simple_rows(3)]))
    s = read_motive_csv(path)
    assert s.meta["skipped"] == {"Rigid Body Marker": ["E:Marker1"]}
    assert not any("not read" in w for w in s.meta["warnings"])


@pytest.mark.parametrize("command", ["identify", "residual", "convert", "inspect"])
def test_a_file_without_rigid_bodies_is_refused_by_every_command_that_writes(tmp_path, command, capsys):
    from euc_ros.cli.main import main
    from euc_ros.core.session import default_session, save_session

    src = _skeleton_file(tmp_path, with_euc=False)
    save_session(default_session(), tmp_path / "session.yaml")
    out = tmp_path / "out"
    argv = {"identify": ["identify", str(tmp_path / "session.yaml"), str(src), "--json", str(out), "--no-progress"],
            "residual": ["residual", str(tmp_path / "session.yaml"), str(src), "--json", str(out), "--no-progress"],
            "convert": ["convert", str(src), str(out)],
            "inspect": ["inspect", str(src)]}[command]
    code = main(argv)
    captured = capsys.readouterr()
    if command == "inspect":           # shows what the file holds, writes nothing
        assert code == 0 and "13 Bone" in captured.out
        return
    assert code == 2 and not out.exists()
    err = captured.err.strip().splitlines()
    assert len(err) == 1 and str(src) in err[0] and "no rigid bodies" in err[0] and "13 Bone" in err[0], err
    assert "skeleton bones are not read" in err[0]


@needs_real
@pytest.mark.shared
def test_real_markers_only_export_is_refused_with_what_it_holds(tmp_path, capsys):
    from euc_ros.cli.main import main

    src = REAL / "ha5dzs_markers_only_360hz_mm_v1.23.csv"
    assert main(["convert", str(src), str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "no rigid bodies" in err and "18 Marker" in err and not (tmp_path / "out").exists()
