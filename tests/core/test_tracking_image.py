"""core.tracking.image against scipy.ndimage (the independent reference)."""

import numpy as np
import pytest
from scipy import ndimage

from core.tracking import image as im

RNG = np.random.default_rng(0)


@pytest.fixture(params=[(17, 23), (32, 40), (9, 8)])
def img(request):
    return RNG.random(request.param).astype(np.float32)


def test_central_derivatives_match_scipy(img):
    e_u, e_v = im.central_derivatives(img)
    ref_u = ndimage.correlate1d(img.astype(float), [-0.5, 0.0, 0.5], axis=1, mode="nearest")
    ref_v = ndimage.correlate1d(img.astype(float), [-0.5, 0.0, 0.5], axis=0, mode="nearest")
    np.testing.assert_allclose(e_u, ref_u, atol=1e-6)
    np.testing.assert_allclose(e_v, ref_v, atol=1e-6)


def test_central_derivatives_batched_equal_single(img):
    stack = np.stack([img, 2 * img, img[::-1]])
    e_u, e_v = im.central_derivatives(stack)
    for k in range(3):
        u1, v1 = im.central_derivatives(stack[k])
        np.testing.assert_array_equal(e_u[k], u1)
        np.testing.assert_array_equal(e_v[k], v1)


@pytest.mark.parametrize("sigma", [0.7, 1.5, 3.0])
def test_gaussian_blur_matches_scipy(img, sigma):
    ours = im.gaussian_blur(img.astype(float), sigma)
    ref = ndimage.gaussian_filter(img.astype(float), sigma, mode="nearest", truncate=4.0)
    np.testing.assert_allclose(ours, ref, atol=1e-12)


def test_gaussian_kernel_matches_scipy_impulse():
    impulse = np.zeros(41)
    impulse[20] = 1.0
    ref = ndimage.gaussian_filter1d(impulse, 2.3, mode="constant")
    w = im.gaussian_kernel1d(2.3)
    r = len(w) // 2
    np.testing.assert_allclose(ref[20 - r:21 + r], w, atol=1e-15)


def test_pyr_down_matches_scipy_binomial(img):
    w = np.array([1.0, 3.0, 3.0, 1.0]) / 8.0
    f = img.astype(float)
    # SciPy centres an even kernel of length 4 at tap 2: out[k] = sum_j w[j] E[k + j - 2],
    # so output 2i + 1 is (E[2i-1] + 3E[2i] + 3E[2i+1] + E[2i+2]) / 8 -- our pixel i.
    ref = ndimage.correlate1d(ndimage.correlate1d(f, w, axis=0, mode="nearest"), w, axis=1,
                              mode="nearest")
    h, wd = f.shape[0] // 2, f.shape[1] // 2
    expected = ref[1:2 * h:2, 1:2 * wd:2]
    # Odd sizes drop the last row/column but still use it as the neighbour, as SciPy does.
    np.testing.assert_allclose(im.pyr_down(f), expected, atol=1e-12)


def test_pyramid_keeps_mean_and_alignment():
    # A linear ramp stays a ramp on the 2x2-aligned grid: level-1 pixel i sits at level-0
    # coordinate 2i + 0.5 (camera.at_level), so the value there is the ramp's value.
    v, u = np.mgrid[0:64, 0:64].astype(float)
    ramp = 0.3 * u + 0.2 * v
    levels = im.gaussian_pyramid(ramp, 3)
    for level, e in enumerate(levels):
        s = 2 ** level
        vv, uu = np.mgrid[0:e.shape[0], 0:e.shape[1]].astype(float)
        expected = 0.3 * (s * uu + (s - 1) / 2) + 0.2 * (s * vv + (s - 1) / 2)
        inner = (slice(2, -2), slice(2, -2))
        np.testing.assert_allclose(e[inner], expected[inner], atol=1e-9)


def test_bilinear_matches_map_coordinates(img):
    h, w = img.shape
    u = RNG.uniform(-2.0, w + 1.0, 500)
    v = RNG.uniform(-2.0, h + 1.0, 500)
    ref = ndimage.map_coordinates(img.astype(float), [v, u], order=1, mode="nearest")
    np.testing.assert_allclose(im.bilinear(img, u, v), ref, atol=1e-6)


def test_sample_with_gradient_equals_sampling_derivative_images(img):
    h, w = img.shape
    u = RNG.uniform(-2.0, w + 1.0, 500)
    v = RNG.uniform(-2.0, h + 1.0, 500)
    f = img.astype(float)
    value, e_u, e_v = im.sample_with_gradient(f, u, v)
    du, dv = im.central_derivatives(f)
    np.testing.assert_allclose(value, ndimage.map_coordinates(f, [v, u], order=1, mode="nearest"),
                               atol=1e-12)
    np.testing.assert_allclose(e_u, ndimage.map_coordinates(du, [v, u], order=1, mode="nearest"),
                               atol=1e-12)
    np.testing.assert_allclose(e_v, ndimage.map_coordinates(dv, [v, u], order=1, mode="nearest"),
                               atol=1e-12)


def test_sampling_survives_non_finite_coordinates(img):
    u = np.array([np.nan, np.inf, -np.inf, 1.0])
    v = np.array([0.0, np.nan, 2.0, 1.0])
    out = im.bilinear(img, u, v)
    assert np.all(np.isfinite(out))
    assert np.all(np.isfinite(np.stack(im.sample_with_gradient(img, u, v))))


def test_grayscale_matches_pillow_luma():
    from PIL import Image
    rgb = RNG.integers(0, 256, (20, 30, 3), dtype=np.uint8)
    ref = np.asarray(Image.fromarray(rgb).convert("L"), dtype=float) / 255.0
    ours = im.to_grayscale(rgb, weights=(0.299, 0.587, 0.114))
    assert ours.dtype == np.float32
    # Pillow rounds to 8 bits.
    np.testing.assert_allclose(ours, ref, atol=0.51 / 255.0)


def test_bad_shapes_raise():
    with pytest.raises(ValueError, match="Expected shape"):
        im.to_grayscale(np.zeros((4, 4)))
    with pytest.raises(ValueError, match="frames"):
        im.bilinear(np.zeros((2, 4, 4)), [0.0], [0.0])
    with pytest.raises(ValueError, match="Expected shape"):
        im.bilinear(np.zeros((2, 2, 4, 4)), [0.0], [0.0])
    with pytest.raises(ValueError, match="levels"):
        im.gaussian_pyramid(np.zeros((4, 4)), 0)


def test_stack_sampling_equals_per_image_sampling():
    stack = RNG.random((4, 13, 17)).astype(np.float32)
    u = RNG.uniform(-1.0, 18.0, 300)
    v = RNG.uniform(-1.0, 14.0, 300)
    frames = RNG.integers(0, 4, 300)
    value = im.bilinear(stack, u, v, frames)
    full = im.sample_with_gradient(stack, u, v, frames)
    for f in range(4):
        sel = frames == f
        np.testing.assert_array_equal(value[sel], im.bilinear(stack[f], u[sel], v[sel]))
        for a, b in zip(full, im.sample_with_gradient(stack[f], u[sel], v[sel])):
            np.testing.assert_array_equal(a[sel], b)
