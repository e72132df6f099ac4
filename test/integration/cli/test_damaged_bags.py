"""Damaged bags give one line naming the file and what to do, in every command.

Real MCAP files written by the project's writer, then damaged the way recordings get damaged: cut
mid-file (recorder killed), metadata.yaml broken or missing, the .mcap copied alone.
"""
from __future__ import annotations

import shutil

import numpy as np
import pytest

from euc_ros.cli.main import main
from euc_ros.core.io.bags import read_mocap_bag, write_mocap_bag
from euc_ros.core.session import save_session


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride

    d = tmp_path_factory.mktemp("bags")
    ride = simulate_ride(RideConfig(runs=1, seed=2, duration_s=3.0))
    save_session(ride.session, d / "session.yaml")
    series = ride.runs[0].mocap
    good = d / "good"
    write_mocap_bag(series, good, chunk_size=16 * 1024)     # small chunks: a cut file keeps most of them
    mcap = next(good.glob("*.mcap"))
    made = {"good": good}
    for cut in (0.3, 0.7, 0.95):
        b = d / f"cut{int(cut * 100)}"
        shutil.copytree(good, b)
        f = next(b.glob("*.mcap"))
        f.write_bytes(mcap.read_bytes()[:int(cut * mcap.stat().st_size)])
        made[b.name] = b
    b = d / "brokenmeta"
    shutil.copytree(good, b)
    (b / "metadata.yaml").write_text("rosbag2_bagfile_information: [unclosed\n")
    made["brokenmeta"] = b
    b = d / "wrongmeta"
    shutil.copytree(good, b)
    (b / "metadata.yaml").write_text("something_else: 1\n")
    made["wrongmeta"] = b
    b = d / "nometa"
    shutil.copytree(good, b)
    (b / "metadata.yaml").unlink()
    made["nometa"] = b
    shutil.copy(mcap, d / "alone.mcap")
    made["alone"] = d / "alone.mcap"
    return d, series, made


def _cmd(name, d, bag, tmp_path):
    return {"identify": ["identify", str(d / "session.yaml"), str(bag), "--no-progress"],
            "residual": ["residual", str(d / "session.yaml"), str(bag), "--json", str(tmp_path / "r.json"),
                         "--no-progress"],
            "convert": ["convert", str(bag), str(tmp_path / "out.csv")],
            "play": ["play", str(bag)]}[name]


@pytest.mark.parametrize("damage,what", [("cut30", "truncated MCAP"), ("cut70", "truncated MCAP"),
                                         ("brokenmeta", "not valid YAML"), ("wrongmeta", "rosbag2_bagfile_information"),
                                         ("nometa", "no metadata.yaml")])
@pytest.mark.parametrize("command", ["identify", "residual", "convert", "play"])
def test_damaged_bag_is_one_line_naming_the_file_and_the_fix(bags, damage, what, command, tmp_path, capsys):
    d, _, made = bags
    rc = main(_cmd(command, d, made[damage], tmp_path))
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1, err
    assert damage in err[0] and what in err[0] and "euc-ros recover" in err[0], err[0]


def test_standalone_mcap_is_read_like_its_bag(bags):
    _, series, made = bags
    a, b = read_mocap_bag(made["alone"]), read_mocap_bag(made["good"])
    assert a.bodies == b.bodies and a.n_frames == b.n_frames == series.n_frames
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(a.frame, b.frame)
    assert a.name == "alone"


@pytest.mark.parametrize("damage", ["cut70", "cut95", "nometa", "brokenmeta", "alone"])
def test_recover_rebuilds_what_was_flushed(bags, damage, tmp_path, capsys):
    _, series, made = bags
    out = tmp_path / "rec"
    assert main(["recover", str(made[damage]), "--out", str(out)]) == 0
    assert "recover:" in capsys.readouterr().out
    got = read_mocap_bag(out)
    # whole chunks only: a prefix of the frames, each one identical to the recording
    assert 0 < got.n_frames <= series.n_frames
    if damage in ("nometa", "brokenmeta", "alone"):
        assert got.n_frames == series.n_frames
    k = np.searchsorted(series.frame, got.frame)
    np.testing.assert_array_equal(series.frame[k], got.frame)
    np.testing.assert_array_equal(np.nan_to_num(series.position[:, k]), np.nan_to_num(got.position))
    assert main(["recover", str(made[damage]), "--out", str(out)]) == 2     # never overwrites


def test_recover_refuses_a_bag_that_a_live_process_holds_open(bags, tmp_path, capsys):
    import subprocess
    import sys

    d, _, made = bags
    bag = tmp_path / "live"
    shutil.copytree(made["cut70"], bag)
    mcap = next(bag.glob("*.mcap"))
    holder = subprocess.Popen([sys.executable, "-c", f"f = open({str(mcap)!r}, 'ab'); print('open', flush=True); "
                               "import time; time.sleep(60)"], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "open"
        assert main(["recover", str(bag), "--out", str(tmp_path / "out")]) == 2
        err = capsys.readouterr().err
        assert str(bag) in err and f"pid {holder.pid}" in err and "still open" in err, err
        assert not (tmp_path / "out").exists()
    finally:
        holder.kill()
        holder.wait()
    assert main(["recover", str(bag), "--out", str(tmp_path / "out")]) == 0     # its writer is gone: recovered
