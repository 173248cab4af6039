"""Camera preprocessing: the impulse-noise and haze estimates, and the cleaning they drive."""

import numpy as np
import pytest

from smokyslam.config import CameraModelConfig, CameraOdometryConfig
from smokyslam.frontends.camera.preprocess import (
    Preprocessor,
    dark_level,
    estimate_impulse_fraction,
    rms_contrast,
)
from smokyslam.sim.camera import CameraRenderer
from smokyslam.sim.world import box_world


def salt_and_pepper(image: np.ndarray, fraction: float, seed: int) -> np.ndarray:
    """Exactly round(fraction * size) distinct pixels set to 0 or 255 with equal odds."""
    rng = np.random.default_rng(seed)
    noisy = image.copy()
    n = round(fraction * image.size)
    pixels = rng.choice(image.size, n, replace=False)
    noisy.reshape(-1)[pixels] = rng.integers(0, 2, n, dtype=np.uint8) * 255
    return noisy


@pytest.fixture(scope="module")
def rendered() -> list[np.ndarray]:
    renderer = CameraRenderer(box_world(), CameraModelConfig(), 1.2, seed=3)
    poses = [[2.0, 3.0, 0.3], [6.0, 3.0, 2.5], [1.0, 1.0, 0.8], [7.0, 5.0, -2.4]]
    return [renderer.render(np.array(p))[0] for p in poses]


@pytest.fixture(scope="module")
def saturated() -> np.ndarray:
    """Smooth random texture with legit black and white blocks (a quarter of the image)."""
    rng = np.random.default_rng(5)
    texture = rng.uniform(30, 225, (30, 40)).repeat(8, axis=0).repeat(8, axis=1)
    image = np.clip(texture + rng.normal(0, 3, texture.shape), 0, 255).astype(np.uint8)
    image[:60, :160] = 0
    image[180:, 160:] = 255
    image[100:140, 200:260] = 255
    return image


@pytest.mark.parametrize("fraction", [0.0, 0.05, 0.1, 0.2, 0.4])
def test_impulse_estimate_reads_back_the_noise_on_rendered_frames(rendered, fraction):
    for i, image in enumerate(rendered):
        noisy = salt_and_pepper(image, fraction, seed=i)
        _, quality = Preprocessor(CameraOdometryConfig()).apply(noisy)
        assert quality.impulse_fraction == pytest.approx(fraction, abs=0.02)


@pytest.mark.parametrize("fraction", [0.0, 0.1, 0.3])
def test_impulse_estimate_ignores_legit_black_and_white_regions(saturated, fraction):
    assert np.mean((saturated == 0) | (saturated == 255)) > 0.2
    noisy = salt_and_pepper(saturated, fraction, seed=1)
    _, quality = Preprocessor(CameraOdometryConfig()).apply(noisy)
    assert quality.impulse_fraction == pytest.approx(fraction, abs=0.02)


def test_clean_frames_pass_untouched(rendered):
    image = rendered[0]
    clean, quality = Preprocessor(CameraOdometryConfig()).apply(image)
    assert quality.median_kernel == 0 and not quality.clahe
    assert np.array_equal(clean, image)
    assert 0.1 < quality.rms_contrast < 0.35


@pytest.mark.parametrize(("fraction", "kernel"), [(0.05, 3), (0.2, 5), (0.4, 5)])
def test_impulses_are_replaced_and_the_rest_kept(rendered, fraction, kernel):
    image = rendered[1]
    noisy = salt_and_pepper(image, fraction, seed=2)
    clean, quality = Preprocessor(CameraOdometryConfig()).apply(noisy)
    assert quality.median_kernel == kernel
    untouched = noisy == image
    assert np.array_equal(clean[untouched], image[untouched])  # only impulses change
    assert np.mean((clean == 0) | (clean == 255)) < 0.003
    rms_after = np.sqrt(np.mean((clean.astype(float) - image) ** 2))
    rms_before = np.sqrt(np.mean((noisy.astype(float) - image) ** 2))
    assert rms_after < 0.15 * rms_before


def test_haze_lowers_contrast_raises_dark_level_and_switches_clahe_with_hysteresis(rendered):
    config = CameraOdometryConfig()
    image = rendered[2]
    hazy = (0.35 * image + 0.65 * 200.0).astype(np.uint8)  # transmission 0.35, airlight 200
    assert rms_contrast(hazy) == pytest.approx(0.35 * rms_contrast(image), rel=0.05)
    assert dark_level(hazy) > dark_level(image) + 0.3
    preprocessor = Preprocessor(config)
    clean, quality = preprocessor.apply(hazy)
    assert quality.clahe
    assert rms_contrast(clean) > 1.5 * rms_contrast(hazy)
    # Between the two thresholds the switch keeps its state.
    middle = 0.5 * (config.clahe_contrast_on + config.clahe_contrast_off)
    t = middle / rms_contrast(image)
    mid = np.clip(t * image + (1 - t) * 200.0, 0, 255).astype(np.uint8)
    assert preprocessor.apply(mid)[1].clahe
    assert not Preprocessor(config).apply(mid)[1].clahe
    assert not preprocessor.apply(image)[1].clahe


def test_estimator_accepts_a_black_image():
    black = np.zeros((240, 320), np.uint8)
    assert estimate_impulse_fraction(black) == 0.0
    _, quality = Preprocessor(CameraOdometryConfig()).apply(black)
    assert quality.rms_contrast == 0.0 and quality.clahe
