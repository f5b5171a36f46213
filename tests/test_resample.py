"""The numpy resize of the default plan's path is skimage's resize, without its import time."""

import numpy as np
import pytest
from skimage.transform import resize

from stringbot.planner.picture.resample import resize_square


@pytest.mark.parametrize("n, m, anti_aliasing", [(401, 256, True), (801, 256, True), (1024, 1001, False),
                                                 (2048, 1001, True), (33, 7, True), (5, 2, True), (3, 40, False),
                                                 (256, 256, True)])
def test_matches_skimage(n, m, anti_aliasing):
    a = np.random.default_rng(n + m).random((n, n))
    ours = resize_square(a, m, anti_aliasing=anti_aliasing)
    assert ours.shape == (m, m)
    np.testing.assert_allclose(ours, resize(a, (m, m), order=1, anti_aliasing=anti_aliasing), atol=1e-9)


def test_refuses_a_non_square():
    with pytest.raises(ValueError, match="expected a square"):
        resize_square(np.zeros((4, 5)), 3)


def test_plan_path_does_not_import_scipy_ndimage_or_skimage_transform(tmp_path):
    """The default plan (polish and preview included) leaves out the slow imports."""
    import subprocess
    import sys

    img = tmp_path / "dots.png"
    from PIL import Image

    pic = np.full((64, 64), 255, np.uint8)
    pic[20:40, 20:40] = 0
    Image.fromarray(pic).save(img)
    code = ("import sys; from stringbot.cli import main\n"
            "try:\n    main([" + ", ".join(repr(x) for x in ["plan", str(img), "-o", str(tmp_path / "p.json"),
                                                             "--pins", "60", "--size", "64", "--polish", "50"]) + "])\n"
            "except SystemExit as e:\n    assert not e.code, e.code\n"
            "print(sorted(m for m in sys.modules if m.startswith(('scipy.ndimage', 'skimage.transform'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip().splitlines()[-1] == "[]"


def test_float32_stays_float32_and_close():
    a = np.random.default_rng(7).random((1024, 1024)).astype(np.float32)
    ours = resize_square(a, 1001, anti_aliasing=False)
    assert ours.dtype == np.float32
    np.testing.assert_allclose(ours, resize(a.astype(float), (1001, 1001), order=1, anti_aliasing=False), atol=1e-5)


@pytest.mark.parametrize("sigma", [0.7, 1.0, 6.0])
def test_gaussian_blur_is_scipys_and_unsharp_steepens_an_edge(sigma):
    from scipy.ndimage import gaussian_filter

    from stringbot.planner.picture.resample import gaussian_blur, unsharp

    a = np.random.default_rng(3).random((40, 40))
    np.testing.assert_allclose(gaussian_blur(a, sigma), gaussian_filter(a, sigma, mode="reflect"), atol=1e-12)
    step = np.zeros((80, 80))
    step[:, 40:] = 0.6
    s = unsharp(step, amount=1.5, sigma=sigma)
    # clipped below the edge, overshooting above it, as it was far from it
    assert s[5, 39] == 0.0 and s[5, 40] > 0.65 and s[5, 79] == pytest.approx(0.6, abs=1e-3)
    assert np.array_equal(unsharp(step, amount=0, sigma=sigma), step)
