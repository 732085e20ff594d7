import numpy as np
import pytest
import scipy.linalg

from lookout import GaussMarkovBias, LinearWaveModel


def test_wave_stationary_std_matches_lyapunov_solution():
    waves = LinearWaveModel(peak_frequency=[0.8976, 0.5, 1.3], damping_ratio=[0.1, 0.05, 0.3], intensity=[2.0, 0.7, 0.01])
    for i in range(3):
        w0, zeta, sigma = (float(np.asarray(a)[i]) for a in (waves.peak_frequency, waves.damping_ratio, waves.intensity))
        A = np.array([[0.0, 1.0], [-(w0**2), -2 * zeta * w0]])
        B = np.array([[0.0], [sigma]])
        P = scipy.linalg.solve_continuous_lyapunov(A, -B @ B.T)
        assert np.sqrt(P[1, 1]) == pytest.approx(float(waves.stationary_std()[i]), rel=1e-12)


def test_wave_amplitude_is_three_sigma_by_default():
    waves = LinearWaveModel.from_amplitude(0.8976, 0.1, [10.0, 10.0, np.radians(1.0)])
    np.testing.assert_allclose(waves.stationary_std(), np.array([10.0, 10.0, np.radians(1.0)]) / 3.0, rtol=1e-12)
    hs = LinearWaveModel.from_significant_wave_height(0.8976, 0.1, 4.0)
    np.testing.assert_allclose(hs.stationary_std(), 1.0, rtol=1e-12)


def test_bias_stationary_std_round_trip():
    bias = GaussMarkovBias.from_stationary_std([1000.0, 500.0, 200.0], [2e3, 1e3, 5e4])
    np.testing.assert_allclose(bias.stationary_std(), [2e3, 1e3, 5e4], rtol=1e-12)


@pytest.mark.parametrize(
    "build, message",
    [
        (lambda: GaussMarkovBias([-1.0, 1.0, 1.0]), "bias time_constant must be positive"),
        (lambda: GaussMarkovBias(1.0, [-1.0, 0.0, 0.0]), "bias noise_gain must be non-negative"),
        (lambda: LinearWaveModel(0.0, 0.1), "wave peak_frequency must be positive"),
        (lambda: LinearWaveModel(0.9, 0.1, [1.0, np.nan, 1.0]), "wave intensity must be finite"),
        (lambda: LinearWaveModel.from_amplitude(0.9, 0.1, [1.0, 2.0]), "wave amplitude must be a scalar or have 3 entries"),
    ],
)
def test_environment_rejects_bad_parameters(build, message):
    with pytest.raises(ValueError, match=message):
        build()
