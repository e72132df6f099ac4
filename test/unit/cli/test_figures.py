"""Figures fit for a paper: every figure of identify and residual rendered and checked, vector formats that
open, the interval drawn where one exists, a report paragraph that states the result with its numbers."""
from __future__ import annotations

import json
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from euc_ros.cli import plots
from euc_ros.cli.main import main

pypdf = pytest.importorskip("pypdf", reason="pypdf (requirements.txt) checks that the PDFs open")


@pytest.fixture(scope="module")
def rolling(tmp_path_factory):
    """Two 6 s rides with rolling resistance: a nearly constant signature, a tie with a discovered term."""
    from euc_ros.core.ridesim.effects import make_effects
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    d = tmp_path_factory.mktemp("fig")
    write_ride(simulate_ride(RideConfig(maneuver="deceleration", runs=2, seed=4, duration_s=6.0,
                                        effects=make_effects(["rolling_resistance"]))), d)
    return d / "session.yaml", sorted(d.glob("*.csv"))


@pytest.fixture
def strict(monkeypatch):
    monkeypatch.setenv("EUC_ROS_STRICT_FIGURES", "1")    # any layout problem fails the command
    yield
    plots.configure()


def _check_outputs(folder, stems, formats):
    for stem in stems:
        for fmt in formats:
            f = folder / f"{stem}.{fmt}"
            assert f.is_file() and f.stat().st_size > 1000, f
            if fmt == "pdf":
                doc = pypdf.PdfReader(str(f))
                assert len(doc.pages) == 1
                box = doc.pages[0].mediabox
                assert float(box.width) > 100 and float(box.height) > 100
            elif fmt == "svg":
                assert ET.parse(f).getroot().tag.endswith("svg")


def test_residual_figures_pass_the_rendering_checks_in_every_format(rolling, tmp_path, strict):
    session, csvs = rolling
    figs, report = tmp_path / "fig", tmp_path / "report.md"
    assert main(["residual", str(session), *map(str, csvs), "--json", str(tmp_path / "r.json"), "--plots", str(figs),
                 "--plot-format", "png,pdf,svg", "--dpi", "150", "--report", str(report), "--no-progress"]) == 0
    stems = sorted({p.stem for p in figs.iterdir()})
    assert {"residual_time", "residual_signature", "rmse_before_after", "candidates"} <= set(stems)
    _check_outputs(figs, stems, ("png", "pdf", "svg"))
    from PIL import Image

    with Image.open(figs / "residual_time.png") as im:     # --dpi is applied to the raster
        w, _ = im.size
    assert w == pytest.approx(9 * 150, abs=2)
    data = json.loads((tmp_path / "r.json").read_text())
    text = report.read_text()
    assert "## Summary" in text and f"h = {data['h_m']:.3f} m" in text and f"{data['rmse_after_nm']:.2f} N m" in text


def test_identify_rmse_curves_show_the_interval(rolling, tmp_path, strict):
    session, csvs = rolling
    figs = tmp_path / "fig"
    assert main(["identify", str(session), *map(str, csvs), "--json", str(tmp_path / "h.json"), "--plots", str(figs),
                 "--plot-format", "pdf", "--no-progress"]) == 0
    _check_outputs(figs, ["rmse_curves", *[f"{c.stem}_states" for c in csvs]], ("pdf",))
    lo, hi = json.loads((tmp_path / "h.json").read_text())["h_ci95_m"]
    # the interval's label is in the PDF's text
    assert f"[{lo:.3f}, {hi:.3f}]" in pypdf.PdfReader(str(figs / "rmse_curves.pdf")).pages[0].extract_text()


def test_the_checks_catch_what_they_claim(strict):
    plt = plots.pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(4, 3))
    x = np.linspace(0, 1, 50)
    a.plot(x, x, label="a very long legend label that sits right on the data")
    a.legend(loc="center")                        # over the line
    fig.text(0.95, 0.5, "a label running off the canvas edge")
    problems = plots.figure_problems(fig)          # b is empty
    assert any("legend" in p for p in problems)
    assert any("empty" in p for p in problems)
    assert any("cut by the canvas edge" in p for p in problems)
    plt.close(fig)


def test_bad_format_and_dpi_are_one_line_errors(rolling, tmp_path, capsys):
    session, csvs = rolling
    assert main(["identify", str(session), str(csvs[0]), "--plots", str(tmp_path / "f"), "--plot-format", "jpg",
                 "--no-progress"]) == 2
    assert "--plot-format" in capsys.readouterr().err
