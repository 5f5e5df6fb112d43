"""scanner.photo.decode: the RGB image OpenCV's colour decoding gives, whichever way it is reached."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from scanner import photo


def _rgb(shape: tuple[int, ...], dtype: type = np.uint8) -> np.ndarray:
    rng = np.random.default_rng(sum(shape))
    top = np.iinfo(dtype).max
    smooth = np.linspace(0, top, shape[0] * shape[1]).reshape(shape[:2])
    noise = rng.integers(0, top // 8, shape, endpoint=True)
    image = (smooth[..., None] if len(shape) == 3 else smooth) + noise
    return np.clip(image, 0, top).astype(dtype)


def _encoded(extension: str, image: np.ndarray, params: tuple[int, ...] = ()) -> bytes:
    ok, data = cv2.imencode(extension, image, list(params))
    assert ok
    return data.tobytes()


FILES = {
    "PNG, 8-bit colour": _encoded(".png", _rgb((37, 53, 3))),
    "PNG, 8-bit gray": _encoded(".png", _rgb((37, 53))),
    "PNG, 8-bit with alpha": _encoded(".png", _rgb((37, 53, 4))),
    "PNG, 16-bit colour": _encoded(".png", _rgb((37, 53, 3), np.uint16)),
    "PNG, 16-bit gray": _encoded(".png", _rgb((37, 53), np.uint16)),
    "PNG, 1-bit": _encoded(".png", (_rgb((37, 53)) > 128).astype(np.uint8), (cv2.IMWRITE_PNG_BILEVEL, 1)),
    "JPEG, colour": _encoded(".jpg", _rgb((37, 53, 3)), (cv2.IMWRITE_JPEG_QUALITY, 90)),
    "JPEG, gray": _encoded(".jpg", _rgb((37, 53)), (cv2.IMWRITE_JPEG_QUALITY, 90)),
    "JPEG, progressive 4:2:0": _encoded(".jpg", _rgb((37, 53, 3)), (cv2.IMWRITE_JPEG_PROGRESSIVE, 1)),
}


@pytest.mark.parametrize("data", FILES.values(), ids=FILES.keys())
@pytest.mark.parametrize("straight_to_rgb", [True, False], ids=["decoded as RGB", "decoded as BGR, converted"])
def test_a_photo_decodes_to_the_values_of_opencvs_colour_decoding_in_rgb_order(data, straight_to_rgb, monkeypatch):
    """``IMREAD_COLOR_RGB`` (OpenCV >= 4.11) and ``IMREAD_COLOR`` + ``COLOR_BGR2RGB`` (older versions, and the
    reference): bit for bit the same image, for every PNG and JPEG form a lab's photos may come in."""
    if straight_to_rgb and not hasattr(cv2, "IMREAD_COLOR_RGB"):
        pytest.skip(f"OpenCV {cv2.__version__} has no IMREAD_COLOR_RGB")
    flag = cv2.IMREAD_COLOR_RGB if straight_to_rgb else 0
    monkeypatch.setattr(photo, "_imread_rgb", lambda: flag)
    expected = cv2.cvtColor(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR), cv2.COLOR_BGR2RGB)
    decoded = photo.decode(data, limit=10_000)
    assert decoded.dtype == np.uint8 and decoded.shape == (37, 53, 3)
    assert np.array_equal(decoded, expected)


def test_the_colour_channels_come_out_in_rgb_order():
    red = np.zeros((20, 20, 3), np.uint8)
    red[..., 2] = 255  # OpenCV writes BGR: this is pure red
    for extension in (".png", ".jpg"):
        decoded = photo.decode(_encoded(extension, red))
        assert (decoded[..., 0] > 250).all() and (decoded[..., 1:] < 5).all()
