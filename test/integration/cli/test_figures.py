"""Figures fit for a paper: every figure of identify and residual rendered and checked, vector formats that
open, the interval drawn where one exists, a report paragraph that states the result with its numbers; fonts
a journal accepts (TrueType in PDF, text in SVG), every h with its identifiability, refused candidates marked,
interval bars on the h range, gaps in the recordings shaded."""
# covers: euc_ros/core/residual/pipeline.py
from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from euc_ros.cli import figures
from euc_ros.cli.figures import (
    STATUS_COLOURS,
    candidate_rows,
    draw_candidates,
    draw_h_range,
    draw_residual_time,
    h_status,
)
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
    figures.configure()


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
    plt = figures.pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(4, 3))
    x = np.linspace(0, 1, 50)
    a.plot(x, x, label="a very long legend label that sits right on the data")
    a.legend(loc="center")                        # over the line
    fig.text(0.95, 0.5, "a label running off the canvas edge")
    problems = figures.figure_problems(fig)          # b is empty
    assert any("legend" in p for p in problems)
    assert any("empty" in p for p in problems)
    assert any("cut by the canvas edge" in p for p in problems)
    plt.close(fig)


def test_bad_format_and_dpi_are_one_line_errors(rolling, tmp_path, capsys):
    session, csvs = rolling
    assert main(["identify", str(session), str(csvs[0]), "--plots", str(tmp_path / "f"), "--plot-format", "jpg",
                 "--no-progress"]) == 2
    assert "--plot-format" in capsys.readouterr().err


# ---- helpers ---------------------------------------------------------------------------------------------------

SVG = "{http://www.w3.org/2000/svg}"


def _pdf_fonts(path) -> list[tuple[str, ...]]:
    """The subtype of every font the PDF's pages use (with a Type0 font's descendants), through their resources
    and those of their form XObjects."""
    fonts, seen = [], set()

    def walk(res):
        res = res.get_object() if res is not None else None
        if not res:
            return
        for ref in (res.get("/Font") or {}).values():
            f = ref.get_object()
            descendants = [str(d.get_object()["/Subtype"]) for d in f.get("/DescendantFonts", [])]
            fonts.append((str(f["/Subtype"]), *descendants))
        for ref in (res.get("/XObject") or {}).values():
            x = ref.get_object()
            if id(x) not in seen:
                seen.add(id(x))
                walk(x.get("/Resources"))

    for page in pypdf.PdfReader(str(path)).pages:
        walk(page.get("/Resources"))
    return fonts


def _assert_truetype_pdf(path):
    fonts = _pdf_fonts(path)
    assert fonts, f"{path.name}: no fonts (text drawn as paths?)"
    assert all(f in {("/TrueType",), ("/Type0", "/CIDFontType2")} for f in fonts), fonts
    raw = path.read_bytes()
    # matplotlib writes its objects uncompressed (no object streams), so the font dictionaries are in the bytes
    assert b"/ObjStm" not in raw
    assert re.search(rb"/Subtype\s*/CIDFontType2|/Subtype\s*/TrueType", raw)
    assert not re.search(rb"/Subtype\s*/Type3", raw)


def _svg_texts(path) -> list[str]:
    """The text of every ``<text>`` element of an SVG."""
    root = ET.parse(path).getroot()
    return ["".join(t.itertext()) for t in root.iter(f"{SVG}text")]


def _fig_texts(fig) -> list[str]:
    """The strings of every text artist of ``fig``, table cells included."""
    from matplotlib.text import Text

    cells = [c.get_text().get_text() for ax in fig.axes for tb in ax.tables for c in tb.get_celld().values()]
    return [t.get_text() for t in fig.findobj(Text)] + cells


def _spans(ax) -> np.ndarray:
    """The spans [x0, x1] of the gap shading of ``ax`` ((0, 2) without)."""
    colls = [c for c in ax.collections if c.get_gid() == figures.GAP_GID]
    if not colls:
        return np.zeros((0, 2))
    paths = [p.vertices for c in colls for p in c.get_paths()]
    return np.array([[v[:, 0].min(), v[:, 0].max()] for v in paths])


def _inside(t, spans, *, strict: bool) -> np.ndarray:
    """Which times lie in one of the spans (inside, or on or inside)."""
    t = np.asarray(t, float)[:, None]
    a, b = spans[:, 0][None, :], spans[:, 1][None, :]
    hit = (t > a) & (t < b) if strict else (t >= a - 1e-9) & (t <= b + 1e-9)
    return hit.any(axis=1)


# ---- fixtures --------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def rolling_run(rolling):
    """The residual analysis of the rolling rides: (result, JSON document, states, params, prepared recordings)."""
    from euc_ros.core.residual.pipeline import trace_residual
    from euc_ros.core.states.contexts import prepare

    session, csvs = rolling
    run = trace_residual(session, csvs)
    result, data, states, params = run.result, run.data, run.states, run.params
    return result, data, states, params, prepare(states, params, floor=result.floor_fit)


@pytest.fixture(scope="module")
def gappy(tmp_path_factory):
    """One 6 s ride with three occlusion gaps of 0.2-0.4 s: too short for h to be identifiable."""
    from euc_ros.core.ridesim.mocap_synth import MocapNoise
    from euc_ros.core.ridesim.simulate import RideConfig, simulate_ride
    from euc_ros.core.ridesim.writers import write_ride

    d = tmp_path_factory.mktemp("gappy")
    write_ride(simulate_ride(RideConfig(maneuver="deceleration", runs=1, seed=4, duration_s=6.0,
                                        noise=MocapNoise(gaps=3, gap_min_s=0.2, gap_max_s=0.4))), d)
    return d / "session.yaml", sorted(d.glob("*.csv"))


def _doc(**extra) -> dict:
    """A residual JSON document, small and complete for the figures: one selected effect in a tie with a
    discovered term, one refused by its row, one refused only in ``refused``, one not admissible, one
    undetectable, one not significant."""
    doc = {
        "h_m": 0.653, "h_ci95_m": [0.594, 0.693], "identifiable": False, "identifiability_reason": "too short",
        "effect": "rolling_resistance", "h_after_m": 0.600, "h_after_ci95_m": [0.559, 0.632],
        "h_after_identifiable": True, "significance_level": 0.01, "ambiguous_with": ["discovered: drift"],
        "selection_steps": [{"model": "none", "selected": "rolling_resistance"},
                            {"model": "rolling_resistance", "selected": None}],
        "ties": [{"effects": ["rolling_resistance", "discovered: drift"], "h_m": [0.600, 0.6001]}],
        "tied_models": [{"effect": "rolling_resistance", "h_m": 0.600, "tie": "selected"},
                        {"effect": "discovered: drift", "h_m": 0.6001}],
        "h_range_m": [0.600, 0.6001],
        "refused": [{"effect": "mocap_time_offset", "text": "refused mocap_time_offset: dt_ms=-1.242 outside "
                     "plausible [-0.95, 1.05] ms", "rmse_after_nm": 0.48}],
        "candidates": [
            {"effect": "rolling_resistance", "rmse_after_nm": 0.348, "p_value": 6e-6, "p_adjusted": 1e-4,
             "detectable": True, "effect_parameters": {"c_rr": 0.0156}},
            {"effect": "mocap_time_offset", "rmse_after_nm": 0.480, "p_value": 7e-5, "p_adjusted": 5e-4,
             "detectable": True, "effect_parameters": {"dt_ms": -1.24}},
            {"effect": "wheel_radius_error", "rmse_after_nm": 0.577, "p_value": 7e-5, "p_adjusted": 6e-4,
             "detectable": True, "effect_parameters": {"delta_r_m": -0.07},
             "refused": "refused wheel_radius_error: delta_r_m=-0.07052 outside plausible [-0.03, 0.03] m"},
            {"effect": "time_varying_h", "rmse_after_nm": 0.753, "p_value": 0.26, "p_adjusted": 0.8,
             "detectable": True, "effect_parameters": {"amplitude_m": 0.0156}},
            {"effect": "none", "rmse_after_nm": 0.770, "p_value": None, "detectable": True, "effect_parameters": {}},
            {"effect": "tilt_gravity", "rmse_after_nm": 0.774, "p_value": 0.96, "p_adjusted": 1.0,
             "detectable": True, "effect_parameters": {"gain": 10.0},
             "inadmissible": "tilt_gravity: gain = 10 - on its physical bound [0, 10]"},
            {"effect": "wheel_body_friction", "rmse_after_nm": 0.770, "p_value": 1.0, "p_adjusted": None,
             "detectable": False, "effect_parameters": {}},
        ]}
    doc.update(extra)
    return doc


# ---- fonts -----------------------------------------------------------------------------------------------------

def test_save_figure_writes_truetype_fonts_and_svg_text(tmp_path, strict):
    """Whatever the rcParams a figure was made under, the written PDF embeds TrueType fonts (no Type 3) and the
    SVG keeps its text as ``<text>`` elements."""
    import matplotlib

    figures.configure(("pdf", "svg"), strict=True)
    plt = figures.pyplot()
    with matplotlib.rc_context({"pdf.fonttype": 3, "svg.fonttype": "path"}):
        fig, ax = plt.subplots(figsize=(4, 3))
        ax.plot([0, 1], [0, 1])
        ax.set_xlabel(r"$\vartheta$ [deg]")
        figures.save_figure(fig, tmp_path / "f.png", title="a title kept as text")
    _assert_truetype_pdf(tmp_path / "f.pdf")
    texts = _svg_texts(tmp_path / "f.svg")
    assert "a title kept as text" in texts


# ---- identify: fonts, text, the h with its status, gaps ---------------------------------------------------------

@pytest.fixture(scope="module")
def gappy_identify(gappy, tmp_path_factory):
    """``identify --plots`` of the gappy ride in PDF and SVG: (figures folder, JSON document)."""
    session, csvs = gappy
    out = tmp_path_factory.mktemp("gappy_id")
    try:
        figures.configure(strict=True)
        assert main(["identify", str(session), *map(str, csvs), "--json", str(out / "h.json"), "--plots",
                     str(out / "fig"), "--plot-format", "pdf,svg", "--no-progress"]) == 0
    finally:
        figures.configure()
    return out / "fig", json.loads((out / "h.json").read_text())


def test_identify_figures_embed_truetype_and_keep_text(gappy, gappy_identify):
    figs, _ = gappy_identify
    stem = f"{gappy[1][0].stem}_states"
    for name in (stem, "rmse_curves"):
        _assert_truetype_pdf(figs / f"{name}.pdf")
        assert any("RMSE" in t for t in _svg_texts(figs / f"{name}.svg"))


def test_identify_titles_give_an_unidentifiable_h_as_a_best_fit(gappy, gappy_identify):
    figs, data = gappy_identify
    assert data["identifiable"] is False          # the ride is too short: what the figures must say
    h = data["per_recording"][0]["h_m"]          # the recording's own 3-DoF fit, its title's h
    texts = _svg_texts(figs / f"{gappy[1][0].stem}_states.svg")
    title = [t for t in texts if t.startswith(gappy[1][0].stem)]
    assert title and "h not identifiable (best fit " in title[0] and "not for use" in title[0], title
    assert not any(re.search(r"\bh = \d", t) for t in texts)
    assert f"best fit {h:.3f} m" in title[0]
    curves = _svg_texts(figs / "rmse_curves.svg")
    assert any("h not identifiable from these recordings" in t for t in curves)
    assert not any(re.search(r"\bh = \d", t) for t in curves)


def test_h_text_states_the_status():
    assert figures.h_text(0.6667, True) == "h = 0.667 m"
    assert figures.h_text(0.6667, False) == "h not identifiable (best fit 0.667 m, not for use)"
    assert figures.h_text(0.6667, None) == "h = 0.667 m (identifiability not assessed)"
    assert figures.h_text(float("nan"), True) == "h not determined"


def test_gap_spans_cover_invalid_samples_and_missing_frames():
    t = np.arange(20) * 0.1
    t = np.delete(t, [12, 13])                    # two frames not recorded: the step jumps 1.1 -> 1.4
    valid = np.ones(t.size, bool)
    valid[:2] = False                             # the filter's start
    valid[5:8] = False                            # an occlusion
    valid[-1] = False                             # the filter's end
    spans = figures.gap_spans(t, valid)
    np.testing.assert_allclose(spans, [[0.0, 0.2], [0.4, 0.8], [1.1, 1.4], [1.8, 1.9]], atol=1e-12)
    assert figures.gap_spans(t, np.ones(t.size, bool)).shape == (1, 2)      # only the missing frames
    assert figures.gap_spans(t, np.zeros(t.size, bool)).tolist() == [[0.0, t[-1]]]


def test_ride_states_shade_the_occlusion_gaps(gappy, strict):
    from euc_ros.core.session import load_session
    from euc_ros.core.states.load import load_states
    from euc_ros.core.states.settings import ReconstructionSettings

    session, csvs = gappy
    st = load_states(load_session(session), csvs, ReconstructionSettings(window_s=0.2, polyorder=3))[0]
    nan = np.full(st.t.size, np.nan)
    fig = figures.draw_ride_states([st], [(np.where(st.valid, 1.0, nan), np.where(st.valid, 1.1, nan))])
    t = st.t - st.t[0]
    interior = ~st.valid & (t > t[st.valid][0]) & (t < t[st.valid][-1])
    assert interior.any()                         # the ride has gaps between usable stretches
    for ax in fig.axes:
        spans = _spans(ax)
        assert spans.size, "a panel without gap shading"
        assert _inside(t[~st.valid], spans, strict=False).all()      # every unusable sample is shaded
        assert not _inside(t[st.valid], spans, strict=True).any()    # no usable one is
    handles, labels = fig.axes[-1].get_legend_handles_labels()
    assert figures.GAP_LABEL in labels
    assert not figures.figure_problems(fig)
    figures.pyplot().close(fig)


# ---- residual: candidates, h range, gaps, the h with its status ---------------------------------------------------

def test_candidate_rows_mark_every_status():
    rows = {r.effect: r for r in candidate_rows(_doc())}
    assert [r.effect for r in candidate_rows(_doc())] == [c["effect"] for c in _doc()["candidates"]]
    assert rows["rolling_resistance"].status == "selected (tie)"
    assert rows["mocap_time_offset"].status == "refused"              # refused only in the document's list
    assert "dt_ms=-1.242" in rows["mocap_time_offset"].note
    assert rows["wheel_radius_error"].status == "refused"             # refused by its row
    assert rows["time_varying_h"].status == "not significant"
    assert rows["none"].status == "baseline"
    assert rows["tilt_gravity"].status == "not admissible"
    assert "physical bound" in rows["tilt_gravity"].note
    assert rows["wheel_body_friction"].status == "undetectable" and rows["wheel_body_friction"].rmse == "-"
    doc = _doc(effect="none", selection_steps=[{"model": "none", "selected": None}], ties=[], ambiguous_with=[])
    rows = {r.effect: r for r in candidate_rows(doc)}
    assert rows["none"].status == "selected" and rows["rolling_resistance"].status == "not selected"


def test_candidates_figure_shows_the_refusals(strict):
    doc = _doc()
    fig = draw_candidates(doc)
    texts = _fig_texts(fig)
    assert "refused" in texts and "not admissible" in texts and "undetectable" in texts
    assert any(t.startswith("refused wheel_radius_error") for t in "\n".join(texts).splitlines())
    table = fig.axes[0].tables[0]
    cells = table.get_celld()
    effects = [cells[i, 0].get_text().get_text() for i in range(1, len(doc["candidates"]) + 1)]
    for name, status in (("mocap_time_offset", "refused"), ("wheel_radius_error", "refused"),
                         ("rolling_resistance", "selected (tie)")):
        i = effects.index(name) + 1
        assert cells[i, 1].get_text().get_text() == status
        np.testing.assert_allclose(cells[i, 0].get_facecolor()[:3], _rgb(STATUS_COLOURS[status]))
    assert STATUS_COLOURS["refused"] != STATUS_COLOURS["selected"]
    assert not figures.figure_problems(fig)
    figures.pyplot().close(fig)


def _rgb(colour):
    from matplotlib.colors import to_rgb

    return to_rgb(colour)


def _bars(ax) -> dict[float, tuple[float, float]]:
    """Each error bar of ``ax`` by its row: y -> (x low, x high)."""
    from matplotlib.container import ErrorbarContainer

    out = {}
    for c in ax.containers:
        if isinstance(c, ErrorbarContainer):
            for seg in c.lines[2][0].get_segments():
                out[float(seg[0, 1])] = (float(seg[:, 0].min()), float(seg[:, 0].max()))
    return out


def test_h_range_draws_the_intervals_as_bars(strict):
    doc = _doc()
    fig = draw_h_range(doc)
    ax = fig.axes[0]
    bars = _bars(ax)
    rows = [t.get_text() for t in ax.get_yticklabels()]
    base, final = rows.index("base 3-DoF model (no effect)"), rows.index("final model: rolling_resistance")
    np.testing.assert_allclose(bars[base], doc["h_ci95_m"])
    np.testing.assert_allclose(bars[final], doc["h_after_ci95_m"])
    assert len(bars) == 2                         # the tied models have no interval of their own: points
    title = ax.get_title()
    assert "base 3-DoF model: h not identifiable (best fit 0.653 m, not for use)" in title
    assert "final model: h = 0.600 m" in title
    assert not figures.figure_problems(fig)
    figures.pyplot().close(fig)


def test_h_range_draws_an_open_end_as_an_arrow(strict):
    doc = _doc(h_ci95_m=[0.594, None], h_after_ci95_m=[None, 0.632], h_after_identifiable=False)
    fig = draw_h_range(doc)
    ax = fig.axes[0]
    rows = [t.get_text() for t in ax.get_yticklabels()]
    base, final = rows.index("base 3-DoF model (no effect)"), rows.index("final model: rolling_resistance")
    bars = _bars(ax)
    np.testing.assert_allclose(bars[base], [0.594, 0.653])      # bounded below, open above
    np.testing.assert_allclose(bars[final], [0.600, 0.632])     # open below
    arrows = [a for a in ax.texts if getattr(a, "arrow_patch", None) is not None]
    assert sorted((a.xy[0], a.xy[1]) for a in arrows) == [(0.0, final), (1.0, base)]
    assert not any(re.search(r"None|inf|nan", t) for t in _fig_texts(fig))
    assert "final model: h not identifiable (best fit 0.600 m, not for use)" in ax.get_title()
    assert not figures.figure_problems(fig)
    figures.pyplot().close(fig)


def test_h_status_follows_the_document():
    assert h_status(_doc()) == (False, True)
    assert h_status({"h_after_ci95_m": [0.5, None]}) == (None, False)    # an open interval is no identified h
    assert h_status({}) == (None, None)


def test_residual_time_shades_gaps_and_states_the_h(rolling_run, strict):
    result, data, states, _, recs = rolling_run
    from euc_ros.core.model.extended import Model

    for identifiable, expected in ((False, f"h not identifiable (best fit {result.h_base:.3f} m, not for use)"),
                                   (True, f"h = {result.h_base:.3f} m")):
        fig = draw_residual_time(result, recs, states, {**data, "identifiable": identifiable})
        labels = fig.axes[0].get_legend_handles_labels()[1]
        assert f"3-DoF, {expected}" in labels and figures.GAP_LABEL in labels
        for ax, rec, st in zip(fig.axes, recs, states):
            t = st.t - st.t[0]
            _, m0 = Model().residual(rec, np.array([result.h_base]))
            used = np.zeros(t.size, bool)
            used[rec.index[m0]] = True
            spans = _spans(ax)
            assert not used[0] and spans.size     # the filter's start is not usable: shaded from t = 0
            assert _inside(t[~used], spans, strict=False).all()
            assert not _inside(t[used], spans, strict=True).any()
        assert not figures.figure_problems(fig)
        figures.pyplot().close(fig)


def test_residual_write_plots_marks_refusals_and_status(rolling_run, tmp_path, strict):
    """The figures of a real analysis: the candidates figure marks each refused candidate of the JSON, and the
    time series give the h with the document's status."""
    result, data, states, params, _ = rolling_run
    from euc_ros.cli.figures import write_plots

    figures.configure(("svg",), strict=True)
    write_plots(result, states, params, tmp_path, data=data)
    refused = {c["effect"] for c in data["candidates"] if c.get("refused")} | {r["effect"] for r in data["refused"]}
    statuses = {r.effect: r.status for r in candidate_rows(data)}
    assert all(statuses[e] == "refused" for e in refused if e in statuses)
    texts = _svg_texts(tmp_path / "candidates.svg")
    if refused:
        assert "refused" in texts
    base_ok, _ = h_status(data)
    assert any(figures.h_text(data["h_m"], base_ok) in t for t in _svg_texts(tmp_path / "residual_time.svg"))
