"""Allan deviation: white rate noise of density q has ADEV q/√τ (within chi-square confidence)."""

import allantools
import numpy as np
import pytest

from aidnav.analysis.allan import allan_deviation, imu_allan
from aidnav.data import ImuData
from aidnav.sim.imu import ImuSpec, corrupt_imu

CI = 1 - 1e-5  # per τ; ~15 values of τ per test


def within_ci(taus, adev, n_phase, fs, expected):
    for tau, dev, exp in zip(taus, adev, expected, strict=True):
        m = int(round(tau * fs))
        edf = allantools.edf_greenhall(alpha=0, d=2, m=m, N=n_phase, overlapping=True)  # white FM
        lo, hi = allantools.confidence_interval(dev, edf, ci=CI)
        assert lo <= exp <= hi, (tau, dev, exp, lo, hi, edf)


def test_white_noise_adev_is_q_over_sqrt_tau():
    fs, n, q = 100.0, 200_000, 0.01  # q in u/√Hz
    x = np.random.default_rng(2024).normal(0.0, q * np.sqrt(fs), n)
    taus, adev, err, ns = allan_deviation(x, fs)
    assert taus[0] == pytest.approx(1 / fs)
    np.testing.assert_allclose(taus, 2.0 ** np.arange(len(taus)) / fs)
    assert adev.shape == taus.shape == err.shape == ns.shape
    np.testing.assert_allclose(err, adev / np.sqrt(ns))
    assert ns[0] == n - 1  # overlapping: N + 1 phase points − 2m terms
    use = ns > 20
    assert use.sum() >= 10
    within_ci(taus[use], adev[use], n + 1, fs, q / np.sqrt(taus[use]))


def test_columns_and_explicit_taus():
    fs = 50.0
    rng = np.random.default_rng(5)
    x = rng.normal(size=(20_000, 3)) * [1.0, 2.0, 3.0]
    taus, adev, err, ns = allan_deviation(x, fs, taus=[0.02, 0.1, 1.0, 10.0])
    np.testing.assert_allclose(taus, [0.02, 0.1, 1.0, 10.0])
    assert adev.shape == (4, 3) and err.shape == (4, 3) and ns.shape == (4,)
    t1, a1, _, n1 = allan_deviation(x[:, 1], fs, taus=[0.02, 0.1, 1.0, 10.0])
    np.testing.assert_allclose(a1, adev[:, 1])
    np.testing.assert_array_equal(n1, ns)
    with pytest.raises(ValueError):
        allan_deviation(np.zeros(2), fs)


def test_imu_allan_recovers_arw_and_vrw():
    fs, n = 100.0, 100_000
    dt = 1 / fs
    t = dt * np.arange(1, n + 1)
    imu = ImuData(t, np.zeros((n, 3)), np.tile([0, 0, 9.8 * dt], (n, 1)), t0=0.0)
    spec = ImuSpec.from_units(arw_deg_sqrt_h=0.2, vrw_m_s_sqrt_h=0.05)
    noisy, _ = corrupt_imu(imu, spec, np.random.default_rng(9))
    res = imu_allan(noisy)
    taus, ns = res["taus_s"], res["n_clusters"]
    use = ns > 20
    for key, q in (("gyro_adev_rad_s", spec.gyro_arw), ("accel_adev_m_s2", spec.accel_vrw)):
        for ax in range(3):
            within_ci(taus[use], res[key][use, ax], n + 1, fs, q[ax] / np.sqrt(taus[use]))
    # boundary units: ADEV at τ = 1 h [deg/h] equals ARW [deg/√h] / √(1 h) numerically → check the factor
    np.testing.assert_allclose(res["gyro_adev_deg_h"], res["gyro_adev_rad_s"] * 180 / np.pi * 3600)
    np.testing.assert_allclose(res["accel_adev_ug"], res["accel_adev_m_s2"] / 9.80665e-6)
    assert res["fs_hz"] == pytest.approx(fs)


def test_imu_allan_rejects_gaps():
    t = np.r_[np.arange(1, 101), np.arange(103, 200)] * 0.01
    n = len(t)
    imu = ImuData(t, np.zeros((n, 3)), np.zeros((n, 3)), t0=0.0)
    with pytest.raises(ValueError, match="gap"):
        imu_allan(imu)


def test_same_numbers_as_allantools_freq_input():
    """The phase is formed once per channel and given to allantools as phase: the deviations are those of
    ``allantools.oadev(..., data_type="freq")`` to the last bit, with one thread or several."""
    fs = 100.0
    rng = np.random.default_rng(19)
    x = rng.normal(size=(50_000, 3)) * [1e-3, 2e-3, 5e-2] + [0.0, 1e-2, 9.8]
    taus, adev, err, ns = allan_deviation(x, fs)
    _, adev1, _, _ = allan_deviation(x, fs, workers=1)
    np.testing.assert_array_equal(adev, adev1)
    for c in range(3):
        t, d, e, n = allantools.oadev(x[:, c], rate=fs, data_type="freq", taus="octave")
        np.testing.assert_array_equal(t, taus)
        np.testing.assert_array_equal(n, ns)
        np.testing.assert_allclose(d, adev[:, c], rtol=1e-14, atol=0)
        np.testing.assert_allclose(e, err[:, c], rtol=1e-14, atol=0)
    bad = x.copy()
    bad[10, 1] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        allan_deviation(bad, fs)


@pytest.mark.parametrize("taus", ["octave", "decade", "log10", [0.01, 0.03, 0.5, 7.0, 120.0, 1e6]])
def test_fused_kernel_equals_allantools_to_1e12(taus):
    """The fused one-pass kernel against ``allantools.oadev`` (the reference, test-only dependency) on
    rates with a large mean, a random walk and white noise (phase values far larger than the second
    differences: the cancellation that tests the summation), every τ list; relative 1e-12 (issue 29)."""
    fs, n = 200.0, 300_001  # an odd length: the last block is partial
    rng = np.random.default_rng(29)
    x = 9.80665 + 0.02 * rng.standard_normal(n) + np.cumsum(1e-4 * rng.standard_normal(n))
    t, d, e, ns = allan_deviation(x, fs, taus=taus)
    rt, rd, re_, rn = allantools.oadev(x, rate=fs, data_type="freq", taus=np.asarray(taus) if
                                       isinstance(taus, list) else taus)
    np.testing.assert_array_equal(t, rt)
    np.testing.assert_array_equal(ns, rn)
    assert len(t) >= 4 and t[-1] < n / fs
    np.testing.assert_allclose(d, rd, rtol=1e-12, atol=0)
    np.testing.assert_allclose(e, re_, rtol=1e-12, atol=0)


def test_taus_are_checked():
    x = np.random.default_rng(1).standard_normal(1000)
    with pytest.raises(ValueError, match="taus"):
        allan_deviation(x, 10.0, taus="weekly")
    with pytest.raises(ValueError, match="at least 2 terms"):
        allan_deviation(x, 10.0, taus=[60.0])  # 600 samples > half the log


def test_no_allantools_at_run_time():
    """allantools is a test dependency only: the library never imports it."""
    import subprocess
    import sys

    code = ("import sys, numpy as np\n"
            "import aidnav.analysis.characterise, aidnav.analysis.allan as A, aidnav.report.allan_plot\n"
            "A.allan_deviation(np.random.default_rng(0).standard_normal((500, 2)), 10.0)\n"
            "print('allantools' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False", out.stderr


def test_unchecked_samples_and_a_work_array_give_the_same_numbers():
    """``check_finite=False`` (a caller that checked the samples) and a caller's work array for the phase
    (the streamed characterisation hands over its intervals' memory) change nothing; the check is on by
    default."""
    x = np.random.default_rng(29).standard_normal((5000, 3))[:, 1]  # a strided column
    a = allan_deviation(x, 100.0)
    b = allan_deviation(x, 100.0, workers=1, work=np.full(6000, np.nan), check_finite=False)
    for u, v in zip(a, b, strict=True):
        np.testing.assert_array_equal(u, v)
    x[7] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        allan_deviation(x, 100.0)
