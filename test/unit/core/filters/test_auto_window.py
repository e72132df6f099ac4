"""The Savitzky-Golay window chosen from a recording's spectra: kernels, spectra, predictions, choice."""
from __future__ import annotations

import numpy as np
import pytest

from euc_ros.core.filters.auto_window import (
    BRIDGED_GAP,
    SEGMENT_S,
    choose_window,
    displacement_spectrum,
    savgol_kernel,
    savgol_response,
    welch_linear,
)
from euc_ros.core.filters.derivatives import savgol_coefficients

EPS = np.finfo(float).eps


@pytest.mark.parametrize(("window", "order", "dt"), [(13, 4, 1 / 120), (301, 8, 1 / 360), (121, 6, 1 / 100)])
def test_kernels_are_the_projects_filter_and_exact_on_polynomials(window, order, dt):
    c = (window - 1) // 2
    theirs = savgol_coefficients(window, order, dt, [c])[:, 0]
    t = (np.arange(window) - c) * dt
    for d in (0, 1, 2):
        mine = savgol_kernel(window, order, d, dt)
        scale = np.abs(mine).sum()
        assert np.allclose(mine, theirs[d], rtol=0, atol=1e3 * EPS * scale)
        # exact on polynomials up to the order: t^k has the d-th derivative k!/(k-d)! t^(k-d), 0 at t = 0 unless k = d
        for k in range(order + 1):
            expected = float(np.prod(np.arange(1, d + 1))) if k == d else 0.0
            assert mine @ t**k == pytest.approx(expected, abs=1e3 * EPS * scale * np.abs(t).max() ** k)


def test_response_of_a_sinusoid_is_the_kernel_applied_to_it():
    dt, W, p, f = 1 / 120, 41, 6, 3.3
    t = np.arange(-(W // 2), W // 2 + 1) * dt
    for d in (0, 1, 2):
        k = savgol_kernel(W, p, d, dt)
        H = savgol_response(W, p, d, dt, [f])[0]
        # y = exp(2 pi i f t): the estimate at t = 0 is H
        assert k @ np.exp(2j * np.pi * f * t) == pytest.approx(H, abs=1e3 * EPS * np.abs(k).sum())


def test_noise_floor_of_white_noise():
    rng = np.random.default_rng(0)
    dt, sigma, n = 1 / 120, 2e-3, 120 * 240
    t = np.arange(n) * dt
    y = 0.1 * np.sin(2 * np.pi * 0.7 * t) + sigma * rng.standard_normal(n)
    f, S, k = displacement_spectrum(y, dt)
    top = f > 0.6 * f[-1]
    # white noise of variance sigma^2 has the one-sided density 2 sigma^2 dt; the median over m bins
    # (neighbours correlated by the Hann window: m / 2 independent) of an average of k segments
    # scatters by ~1.25 sqrt(2 / (k m)) and sits ~1/(3k) below the mean
    m = int(top.sum())
    tol = 5 * 1.25 * np.sqrt(2 / (k * m)) + 1 / (3 * k)
    assert abs(np.median(S[top]) / (2 * sigma**2 * dt) - 1) <= tol
    est = choose_window(dt, {"y": y})
    assert est.noise_std["y"] == pytest.approx(sigma, rel=tol / 2)      # sigma is the square root


def _lines(freqs, amps, dt, n, rng):
    t = np.arange(n) * dt
    ph = rng.uniform(0, 2 * np.pi, len(freqs))
    y = sum(a * np.sin(2 * np.pi * f * t + p) for f, a, p in zip(freqs, amps, ph, strict=True))
    acc = sum(-a * (2 * np.pi * f) ** 2 * np.sin(2 * np.pi * f * t + p)
              for f, a, p in zip(freqs, amps, ph, strict=True))
    return y, acc


def _line_distortion(freqs, amps, W, p, dt, shift):
    """Relative acceleration distortion of a sum of lines, the lines moved by ``shift`` [Hz]."""
    f = np.asarray(freqs) + shift
    H = savgol_response(W, p, 2, dt, f)
    e2 = np.abs(H / -(2 * np.pi * f) ** 2 - 1) ** 2
    w = (np.asarray(amps) * (2 * np.pi * np.asarray(freqs)) ** 2) ** 2
    return float(np.sqrt(np.sum(e2 * w) / np.sum(w)))


def test_predicted_distortion_and_noise_match_the_filter():
    rng = np.random.default_rng(1)
    dt, n = 1 / 120, 120 * 120
    freqs, amps = [0.4, 1.1, 2.3, 3.6], [0.05, 0.02, 0.004, 0.001]
    y, acc = _lines(freqs, amps, dt, n, rng)
    sigma = 1e-4
    noisy = y + sigma * rng.standard_normal(n)
    ch = choose_window(dt, {"y": noisy}, noise_std={"y": sigma})
    W, p = ch.window, ch.polyorder
    # a line's power spreads over the Hann main lobe, +-2 bins of 1/SEGMENT_S: the prediction lies
    # between the distortions of the lines moved to either edge
    lo = min(_line_distortion(freqs, amps, W, p, dt, s) for s in (-2 / SEGMENT_S, 0.0, 2 / SEGMENT_S))
    hi = max(_line_distortion(freqs, amps, W, p, dt, s) for s in (-2 / SEGMENT_S, 0.0, 2 / SEGMENT_S))
    assert lo * 0.9 <= ch.distortion["y"][2] <= hi * 1.1
    # the noise prediction is sigma^2 sum(w^2), against the acceleration rms of the lines
    k2 = savgol_kernel(W, p, 2, dt)
    assert ch.noise["y"] * ch.acceleration_rms["y"] == pytest.approx(sigma * np.sqrt(k2 @ k2), rel=1e-12)
    assert ch.acceleration_rms["y"] == pytest.approx(np.sqrt(np.mean(acc**2)), rel=0.15)
    # and the filter really does what was predicted, on the interior samples
    est = np.correlate(noisy, k2, mode="valid")
    err = est - acc[W // 2: -(W // 2)]
    predicted = np.hypot(ch.distortion["y"][2], ch.noise["y"]) * np.sqrt(np.mean(acc**2))
    # tolerance: the noise's sample rms over n samples correlated across W (5 standard deviations of
    # sqrt(W / 2n)) and the spread of the line distortion over the main lobe
    tol = 5 * np.sqrt(W / (2 * n)) + (hi - lo) * np.sqrt(np.mean(acc**2)) / predicted
    assert np.sqrt(np.mean(err**2)) == pytest.approx(predicted, rel=tol)


def test_noise_free_fast_motion_gets_a_short_window_and_noisy_slow_motion_a_long_one():
    rng = np.random.default_rng(2)
    dt, n = 1 / 120, 120 * 60
    fast, _ = _lines([1.5, 3.0, 4.5], [0.02, 0.005, 0.002], dt, n, rng)
    slow, _ = _lines([0.2, 0.5], [0.1, 0.02], dt, n, rng)
    a = choose_window(dt, {"g": fast}, noise_std={"g": 1e-9})
    b = choose_window(dt, {"g": slow + 3e-3 * rng.standard_normal(n)})
    assert a.window_s < 0.5 and a.distortion["g"][2] < 0.01
    assert b.window_s > 1.0


@pytest.mark.parametrize(("window", "order"), [(13, 4), (289, 6), (1201, 4)])
@pytest.mark.parametrize("grid", ["dft even", "dft odd", "other"])
def test_response_on_a_dft_grid_and_off_it_is_the_explicit_sum(window, order, grid):
    """The response by one FFT (the weights folded modulo the DFT length, windows longer than it included)
    and by the direct sum, against ``sum_j w_j exp(2 pi i f j dt)`` written out. Both are sums of
    ``window`` terms: round-off ~ window * eps * sum|w|; 1e-12 * sum|w| bounds it for windows up to ~4000."""
    dt = 1 / 120
    f = {"dft even": np.fft.rfftfreq(480, dt), "dft odd": np.fft.rfftfreq(481, 1.0 / (1.0 / dt)),
         "other": np.linspace(0.0, 50.0, 77)}[grid]
    c = (window - 1) // 2
    j = np.arange(-c, c + 1)
    for d in (0, 1, 2):
        w = savgol_kernel(window, order, d, dt)
        ref = np.array([np.sum(w * np.exp(2j * np.pi * fk * j * dt)) for fk in f])
        assert np.max(np.abs(savgol_response(window, order, d, dt, f) - ref)) <= 1e-12 * np.sum(np.abs(w))


@pytest.mark.parametrize("n", [8, 9, 16, 17, 480, 481])
def test_welch_linear_is_scipys_welch_with_linear_detrending(n):
    """The vectorised estimate against scipy's own, on lengths of one segment up to many, odd and even
    segments (the Nyquist bin), signals with an offset and a trend. Both remove the same least-squares line:
    they differ by the rounding of the detrended samples, about eps * n * max|x| / rms(detrended) relative in
    amplitude (here max|x| / rms <= ~50 and n <= 481: ~5e-12); 1e-10 of the largest bin bounds it."""
    from scipy.signal import welch

    rng = np.random.default_rng(n)
    for length in (n, n + 1, 3 * n + 5, 20 * n):
        x = 0.01 * np.cumsum(rng.standard_normal(length)) + 0.2 + 1e-4 * np.arange(length) \
            + 0.01 * rng.standard_normal(length)
        f_ref, p_ref = welch(x, fs=120.0, nperseg=n, detrend="linear")
        f, p = welch_linear(x, 120.0, n)
        np.testing.assert_array_equal(f, f_ref)
        assert np.max(np.abs(p - p_ref)) <= 1e-10 * np.max(p_ref)


def test_signals_whose_stretches_are_all_shorter_than_a_segment_share_the_finest_grid():
    """A short recording with gaps: one signal is continuous, another broken into stretches shorter than a
    Welch segment (its spectrum has fewer bins). The choice runs on one grid, and each signal's white
    floor is read as its own: both carry noise of the same sigma, estimated to within its sampling error."""
    rng = np.random.default_rng(5)
    dt, n, sigma = 1 / 120, 120 * 60, 3e-3
    y, _ = _lines([0.3, 0.8], [0.05, 0.01], dt, n, rng)
    whole = y + sigma * rng.standard_normal(n)
    broken = y + sigma * rng.standard_normal(n)
    stretch = int(0.8 * SEGMENT_S / dt)                 # every stretch shorter than a segment
    gap = BRIDGED_GAP + 1                               # gaps longer than those a stretch continues across
    for a in range(stretch, n, stretch + gap):
        broken[a:a + gap] = np.nan
    assert displacement_spectrum(broken, dt)[0].size < displacement_spectrum(whole, dt)[0].size
    ch = choose_window(dt, {"whole": whole, "broken": broken})
    assert set(ch.distortion) == {"whole", "broken"}
    assert ch.window % 2 == 1 and ch.window > ch.polyorder
    # each floor is the median over ~40+ top-band bins of averages of >= 10 segments: a relative error of
    # a few percent in power, half that in sigma; 0.2 is beyond 5 standard errors
    for name in ("whole", "broken"):
        assert ch.noise_std[name] == pytest.approx(sigma, rel=0.2)


@pytest.mark.parametrize(("first_drop", "drops"), [(8, 12), (60, 12), (300, 12), (3, 144), (3, 720)])
def test_frames_dropped_anywhere_leave_the_spectrum_and_the_choice_as_they_were(first_drop, drops):
    """Frames dropped at random (a Motive export's missing rows, NaN in the signals), one in the first
    Welch segment, then 12 more, 2 % or 10 % of them. The stretches continue across them (the states
    interpolate such gaps too): the spectrum keeps the segments' grid (neither a first stretch shorter than a
    segment nor the short stretches between 2 % dropped may set it: a 6-bin grid shows no motion at all),
    its white floor is the undropped signal's less about twice the share interpolated, and the choice is the
    undropped signal's."""
    rng = np.random.default_rng(int(first_drop) + drops)
    dt, n, sigma = 1 / 120, 120 * 60, 2e-3
    y, _ = _lines([0.3, 0.8, 1.6], [0.05, 0.01, 0.002], dt, n, rng)
    whole = y + sigma * rng.standard_normal(n)
    dropped = whole.copy()
    at = np.concatenate([[first_drop], rng.choice(np.arange(first_drop + 2, n - 1), drops, replace=False)])
    dropped[at] = np.nan
    f_w, S_w, k_w = displacement_spectrum(whole, dt)
    f_d, S_d, k_d = displacement_spectrum(dropped, dt)
    np.testing.assert_array_equal(f_d, f_w)
    top = f_w > 0.6 * f_w[-1]
    # an interpolated sample follows its neighbours: white power at angular frequency w becomes
    # 1 - q/2 + 2 q cos w of itself (first order in q, q the share interpolated: each missing n_j is replaced by
    # the mean of n_{j-1} and n_{j+1}); over the top of the band (0.6-0.95 of Nyquist, median cos w = -0.76)
    # that is 1 - 2.0 q (white noise alone: 1.7-2.2 q for q from 0.2 to 10 %)
    q = np.count_nonzero(np.isnan(dropped)) / n
    # the two floors are medians over the same m bins of averages of ~k segments of nearly the same data:
    # each scatters by ~1.25 sqrt(2 / (k m)) (test_noise_floor_of_white_noise); 5 of those apart at most
    tol = 5 * 1.25 * np.sqrt(2 / (min(k_w, k_d) * int(top.sum())))
    assert abs(np.median(S_d[top]) / np.median(S_w[top]) / (1 - 2 * q) - 1) <= tol
    assert abs(np.median(S_d[top]) / (2 * sigma**2 * dt * (1 - 2 * q)) - 1) <= tol + 1 / (3 * k_d)
    ch_w, ch_d = choose_window(dt, {"y": whole}), choose_window(dt, {"y": dropped})
    assert ch_d.polyorder == ch_w.polyorder
    assert abs(ch_d.window - ch_w.window) <= 0.1 * ch_w.window


def test_choice_on_a_generated_ride_leaves_under_one_percent():
    from euc_ros.core.worldsim import simulate_ride

    ride = simulate_ride(21, 120.0, duration=10.0)
    tr = ride.truth
    sig = {"gamma": tr["gamma"], "phi": tr["phi"], "x": tr["x"]}
    ch = choose_window(1 / 120, sig, noise_std={k: 1e-7 for k in sig})
    for name, key in (("gamma", "gamma_ddot"), ("phi", "phi_ddot"), ("x", "x_ddot")):
        k2 = savgol_kernel(ch.window, ch.polyorder, 2, 1 / 120)
        est = np.correlate(np.asarray(tr[name]), k2, mode="valid")
        ref = np.asarray(tr[key])[ch.window // 2: -(ch.window // 2)]
        assert np.sqrt(np.mean((est - ref) ** 2) / np.mean(ref**2)) < 0.01


def _coloured(rng, n, dt, corner_hz, rms):
    """First-order low-pass white noise of the given RMS (a tracker's smoothing, soft tissue)."""
    from scipy.signal import lfilter

    a = np.exp(-2 * np.pi * corner_hz * dt)
    x = lfilter([1 - a], [1, -a], rng.standard_normal(n + 2000))[2000:]
    return rms * x / np.std(x)


def test_coloured_noise_is_modelled_and_the_choice_follows_the_motion(monkeypatch):
    """Noise low-passed at 3 Hz hides under a white floor read at the top of the band; the choice must
    see it (noise_model "coloured") and filter the accelerations better than the white model's choice."""
    import euc_ros.core.filters.auto_window as aw
    from euc_ros.core.worldsim import simulate_ride

    ride = simulate_ride(33, 120.0, duration=40.0)
    tr = ride.truth
    rng = np.random.default_rng(4)
    n, dt = tr["gamma"].size, 1 / 120
    rms = {"gamma": np.radians(0.3), "phi": np.radians(0.3), "x": 1e-3}
    noisy = {k: np.asarray(tr[k]) + _coloured(rng, n, dt, 3.0, rms[k]) + 1e-5 * rng.standard_normal(n)
             for k in rms}

    def actual(ch):
        errs = []
        k2 = savgol_kernel(ch.window, ch.polyorder, 2, dt)
        for name, key in (("gamma", "gamma_ddot"), ("phi", "phi_ddot"), ("x", "x_ddot")):
            est = np.correlate(noisy[name], k2, mode="valid")
            ref = np.asarray(tr[key])[ch.window // 2: -(ch.window // 2)]
            errs.append(np.sqrt(np.mean((est - ref) ** 2) / np.mean(ref**2)))
        return max(errs)

    ch = choose_window(dt, noisy)
    assert ch.noise_model == "coloured"
    monkeypatch.setattr(aw, "MAX_WHITE_DISTORTION", np.inf)
    white = choose_window(dt, noisy)
    assert white.noise_model == "white" and white.window < ch.window
    assert actual(ch) < actual(white)
    # the clean ride itself: white noise only, the choice is unchanged by the guard
    monkeypatch.undo()
    clean = {k: np.asarray(tr[k]) + 1e-5 * rng.standard_normal(n) for k in rms}
    assert choose_window(dt, clean).noise_model == "white"


def test_recordings_of_different_lengths_pool_their_segments():
    """Several recordings of one rate, of different lengths (a list, as the filter choice passes them): the
    pooled spectrum is the count-weighted mean of each one's own, bin for bin."""
    rng = np.random.default_rng(3)
    dt, sigma = 1 / 120, 2e-3
    ys = []
    for n in (120 * 30, 120 * 45 + 17):
        y, _ = _lines([0.4, 1.1], [0.04, 0.01], dt, n, rng)
        ys.append(y + sigma * rng.standard_normal(n))
    f, S, k = displacement_spectrum(ys, dt)
    parts = [displacement_spectrum(y, dt) for y in ys]
    for fp, _, _ in parts:
        np.testing.assert_array_equal(fp, f)
    assert k == pytest.approx(sum(kp for _, _, kp in parts))
    mean = sum(Sp * kp for _, Sp, kp in parts) / k
    np.testing.assert_allclose(S[1:], mean[1:], rtol=1e-12)
    choose_window(dt, {"y": ys})     # the choice takes them as given


#: Seed of the score-noise test's draws, drawn once from a range by a fixed generator (not picked).
SCORE_NOISE_SEED = int(np.random.default_rng(20261129).integers(0, 10_000))


def test_predicted_scatter_of_the_score_is_its_scatter_over_noise_draws():
    """The score's noise (``score_sd``, ``_difference_variance`` Notes: chi-square bins of the Welch average
    propagated to first order) against the scatter of the score differences over independent draws of a
    signal of known spectrum: Gaussian motion (white noise through a 6th-order low-pass at 2 Hz, so every bin
    is a chi-square variate, as the derivation assumes) plus white pose noise whose floor is read from the
    spectrum. The difference of each candidate's score from a fixed reference (the first draw's choice)
    is collected over ``R`` draws; its sample variance over the variance predicted (the mean of the draws'
    predictions) scatters as chi-square with ``R - 1`` degrees of freedom over ``R - 1``. The candidates' ratios
    come from the same draws, so their geometric mean scatters at most as one of them: it must lie within that
    law's 0.05 % and 99.95 % quantiles. (Single candidates stray further, by up to about 25 % in the standard
    deviation: the band's end is a threshold the derivation holds fixed.)"""
    from scipy.signal import butter, sosfilt
    from scipy.stats import chi2

    import euc_ros.core.filters.auto_window as aw

    rng = np.random.default_rng(SCORE_NOISE_SEED)
    dt, n, sigma, R = 1 / 120, 120 * 30, 2e-3, 100
    sos = butter(6, 2.0, fs=1 / dt, output="sos")

    def spectra():
        motion = sosfilt(sos, rng.standard_normal(n + 2000))[2000:]
        y = 0.5 * motion + sigma * rng.standard_normal(n)
        return aw._spectra_and_floors(dt, {"y": y}, {}, SEGMENT_S)

    def evaluate(sp, ref=None):
        return aw._evaluate(sp, dt, (2, 4), 1.5, SEGMENT_S, 2, False, ref=ref)

    cands, best, *_ = evaluate(spectra())
    ref = cands.index(best)
    diff, var = [], []
    for _ in range(R):
        cands = evaluate(spectra(), ref)[0]
        score = np.array([c["score"] for c in cands])
        diff.append(score - score[ref])
        var.append(np.array([c["score_sd"] for c in cands]) ** 2)
    observed = np.var(diff, axis=0, ddof=1)
    predicted = np.mean(var, axis=0)
    lo, hi = chi2.ppf([0.0005, 0.9995], R - 1) / (R - 1)
    checked = np.flatnonzero(predicted > 0)
    assert checked.size >= 10
    ratio = observed[checked] / predicted[checked]
    assert lo <= np.exp(np.mean(np.log(ratio))) <= hi, (ratio, lo, hi)


def test_a_kept_kernel_is_not_changed_through_what_savgol_kernel_returns():
    # the candidates' kernels are kept between choices; the array a caller gets is its own
    first = savgol_kernel(31, 4, 2, 0.01)
    expected = first.copy()
    first[:] = 0.0
    again = savgol_kernel(31, 4, 2, 0.01)
    assert np.array_equal(again, expected) and again.flags.writeable
