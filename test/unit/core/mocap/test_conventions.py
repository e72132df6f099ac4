"""The up axis checked against the data.

The recordings come from the ride simulator (a Y-up Motive export, as Motive writes by default); the
Z-up export and the Y-up bag are the same frames written with the other convention, so the tests
do not share the inference's assumptions about where the bodies are.
"""
# covers: euc_ros/core/io/recordings.py
# covers: euc_ros/core/mocap/checks.py
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from euc_ros.cli.main import main
from euc_ros.core.errors import ConfigError, InputError
from euc_ros.core.io.motive_csv import read_motive_csv, write_motive_csv
from euc_ros.core.io.recordings import load_recording
from euc_ros.core.mocap.checks import check_recording
from euc_ros.core.mocap.conventions import infer_up_axis, poses_with_up
from euc_ros.core.mocap.series import MocapSeries
from euc_ros.core.session import default_session, load_session, save_session


@pytest.fixture(scope="module")
def files(short_ride, up_axis_csvs):
    """The simulated Y-up CSV, a Z-up export of the same frames, sessions with each world_up."""
    src, _ = short_ride
    yup, zup = up_axis_csvs["y"], up_axis_csvs["z"]
    session = load_session(src / "session.yaml")
    assert session.world_up == "y"
    sessions = {}
    for up in ("y", "z"):
        sessions[up] = yup.parent / f"session_{up}.yaml"
        save_session(replace(session, world_up=up), sessions[up])
    return {"yup": yup, "zup": zup, "session": sessions}


def _one_line_error(capsys) -> str:
    captured = capsys.readouterr()
    lines = [ln for ln in captured.err.splitlines() if ln.strip()]
    assert len(lines) == 1, captured.err
    assert "h [m]" not in captured.out       # no table: nothing identified
    return lines[0]


@pytest.mark.parametrize("command", ["identify", "residual"])
def test_y_up_recording_with_world_up_z_is_refused(files, command, tmp_path, capsys):
    """The issue's example: a Y-up recording with ``world_up: z`` gave h = 0.147 with no warning."""
    args = [command, str(files["session"]["z"]), str(files["yup"]), "--no-progress"]
    if command == "residual":
        args += ["--json", str(tmp_path / "r.json")]
    assert main(args) == 2
    line = _one_line_error(capsys)
    assert f"{files['session']['z']}, key 'world_up'" in line
    assert "world_up is 'z'" in line and "suggest 'y'" in line and "set world_up: y" in line
    assert str(files["yup"]) in line
    assert not (tmp_path / "r.json").exists()


def test_z_up_recording_with_world_up_y_is_refused(files):
    session = load_session(files["session"]["y"])
    series = load_recording(files["zup"], "y")
    with pytest.raises(ConfigError) as info:
        check_recording(series, session, files["zup"])
    assert info.value.key == "world_up" and "suggest 'z'" in str(info.value)
    assert str(files["session"]["y"]) in str(info.value)


@pytest.mark.parametrize("rec, up", [("yup", "y"), ("zup", "z")])
def test_the_right_world_up_passes_without_warning(files, rec, up):
    session = load_session(files["session"][up])
    series = load_recording(files[rec], up)
    assert check_recording(series, session, files[rec]) == []
    info = infer_up_axis(series, session)
    assert info["inferred"] == up and info["conclusive"]
    assert set(info["tests"]) == {"floor", "upright", "wheel_centre", "euc_axis"}


def test_reading_with_the_other_axis_recovers_the_file(files):
    """``poses_with_up`` on a series read as Y-up gives what reading the file as Z-up gives."""
    s_y = read_motive_csv(files["yup"], world_up="y")
    s_z = read_motive_csv(files["yup"], world_up="z")
    pos, quat = poses_with_up(s_y, "z")
    np.testing.assert_array_equal(pos, s_z.position)   # a permutation and a sign: exact
    np.testing.assert_array_equal(quat, s_z.quat)
    back, _ = poses_with_up(s_z, "y")
    np.testing.assert_array_equal(back, s_y.position)
    for i in range(len(s_y.bodies)):                   # one body's poses: that body's of the whole
        p1, q1 = poses_with_up(s_y, "z", i)
        np.testing.assert_array_equal(p1, s_z.position[i])
        np.testing.assert_array_equal(q1, s_z.quat[i])


def test_bag_with_y_up_poses_is_refused(files, tmp_path, capsys):
    """Bags are Z-up by contract: poses published in Motive's Y-up world are an error naming the bag."""
    from euc_ros.core.io.bags import write_mocap_bag

    bag = tmp_path / "yup_bag"
    write_mocap_bag(read_motive_csv(files["yup"], world_up="z"), bag)  # Motive's axes, not converted
    session = load_session(files["session"]["y"])
    with pytest.raises(InputError) as info:
        check_recording(load_recording(bag, "y"), session, bag)
    assert str(bag) in str(info.value) and "not Z-up" in str(info.value) and "y axis" in str(info.value)
    assert main(["identify", str(files["session"]["y"]), str(bag), "--no-progress"]) == 2
    assert "not Z-up" in _one_line_error(capsys)


def test_too_short_is_not_an_error(files):
    """0.3 s: only the floor test applies, which is no ground for an error (a warning says so)."""
    session = load_session(files["session"]["z"])
    s = load_recording(files["yup"], "z")
    keep = s.t < s.t[0] + 0.3
    short = MocapSeries(s.t[keep], s.frame[keep], s.bodies, s.position[:, keep], s.quat[:, keep],
                        s.tracked[:, keep], s.mean_marker_error[:, keep], s.name, dict(s.meta))
    info = infer_up_axis(short, session)
    assert info["inferred"] == "y" and not info["conclusive"] and set(info["tests"]) == {"floor"}
    (warning,) = check_recording(short, session, files["yup"])
    assert "world_up y, not z" in warning and "too little data" in warning


def _lone_euc(y_of_t: np.ndarray) -> MocapSeries:
    """An EUC body alone (no rider), upright, heading +x, wheel centre 0.2 m above the floor, at
    world y = ``y_of_t``, written Y-up and read back (so the file's own axes are Motive's)."""
    session = default_session("y")
    n = y_of_t.size
    t = np.arange(n) / 120.0
    p = np.asarray(session.euc.pivot_to_wheel_center)
    pos = np.zeros((1, n, 3))
    pos[0, :, 1] = y_of_t
    pos[0, :, 2] = session.euc.wheel_radius - p[2]
    quat = np.zeros((1, n, 4))
    quat[..., 3] = 1.0
    s = MocapSeries(t, np.arange(n), ["E"], pos, quat, np.ones((1, n), bool), np.full((1, n), 1e-4), "lone",
                    {"rate_hz": 120.0})
    return s


def test_a_standing_euc_that_fits_both_axes_is_ambiguous_not_an_error(tmp_path):
    """No motion: an EUC standing at file Z = 0.65 m looks, read Z-up, like an EUC whose wheel centre
    is 0.2 m above the floor (its sideways offset 0.65 - 0.45 reads as a height). The data cannot tell."""
    session_y, session_z = default_session("y"), default_session("z")
    s = _lone_euc(np.full(240, -0.65))       # world y -0.65 is file Z +0.65 (Motive Z = -y)
    path = write_motive_csv(s, tmp_path / "still.csv", world_up="y")
    for session in (session_y, session_z):
        series = load_recording(path, session.world_up)
        info = infer_up_axis(series, session)
        assert info["inferred"] == "y or z", info["reason"]
        assert check_recording(series, session, path) == []


def test_the_same_euc_riding_sideways_is_resolved(tmp_path):
    """Moving 2 m along world y, the file Z coordinate is no longer a constant 'height': only Y fits."""
    s = _lone_euc(np.linspace(-0.65, -2.65, 240))
    path = write_motive_csv(s, tmp_path / "across.csv", world_up="y")
    session = default_session("z")
    series = load_recording(path, "z")
    info = infer_up_axis(series, session)
    assert info["inferred"] == "y" and info["tests"]["wheel_centre"]["z"]["spread"] > 1.5
    with pytest.raises(ConfigError, match="suggest 'y'"):
        check_recording(series, session, path)


def test_fitting_neither_axis_is_a_warning(files):
    """A wheel radius 0.15 m off: the session's axis no longer fits and neither does the other."""
    session = load_session(files["session"]["y"])
    wrong = replace(session, euc=replace(session.euc, wheel_radius=0.35))
    series = load_recording(files["yup"], "y")
    (warning,) = check_recording(series, wrong, files["yup"])
    assert "neither up axis" in warning and "wheel_radius" in warning


def test_wheel_centre_evidence_matches_an_independent_computation(files):
    """The wheel-centre height of the inference against C = E + R_E p written out with scipy."""
    from scipy.spatial.transform import Rotation

    session = load_session(files["session"]["y"])
    s = load_recording(files["yup"], "y")
    i = s.bodies.index("E")
    C = s.position[i] + Rotation.from_quat(s.quat[i]).apply(session.euc.pivot_to_wheel_center)
    info = infer_up_axis(s, session)
    # the same numbers through two rotation implementations: round-off of a 3x3 product on ~1 m values
    assert info["tests"]["wheel_centre"]["y"]["value"] == pytest.approx(np.median(C[:, 2]), abs=1e-12)


def test_long_recordings_are_thinned_to_the_same_verdict(files, monkeypatch):
    """Above MAX_FRAMES frames the tests run on evenly spaced frames: same inference, same refusal."""
    import euc_ros.core.mocap.conventions as conv

    session = load_session(files["session"]["z"])
    series = load_recording(files["yup"], "z")
    full = infer_up_axis(series, session)
    monkeypatch.setattr(conv, "MAX_FRAMES", 60)
    thin = infer_up_axis(series, session)
    assert thin["inferred"] == full["inferred"] == "y" and thin["conclusive"]
    assert thin["tests"]["wheel_centre"]["y"]["value"] == pytest.approx(full["tests"]["wheel_centre"]["y"]["value"],
                                                                        abs=0.005)
    with pytest.raises(ConfigError, match="suggest 'y'"):
        check_recording(series, session, files["yup"])
