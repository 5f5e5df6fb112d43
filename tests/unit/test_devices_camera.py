"""The camera through OpenCV reading a video file the test writes, the playback camera, photo uploads."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from scanner.acquisition.config import CameraConfig
from scanner.acquisition.devices.camera import OpenCvCamera, PhotoError, PlaybackCamera, decode_photo
from scanner.acquisition.devices.protocols import DeviceError, DeviceUnavailable
from scanner.acquisition.devices.sources import SimulatedSample


def frames(count: int, shape=(48, 64)) -> list[np.ndarray]:
    """RGB frames with a different random texture each, so every frame can be told apart."""
    rng = np.random.default_rng(0)
    return [rng.integers(0, 256, (*shape, 3), dtype=np.uint8) for _ in range(count)]


@pytest.fixture
def video(tmp_path):
    """A lossless (PNG codec) video of four known frames."""
    path = tmp_path / "tu3.avi"
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"png "), 10, (64, 48))
    if not writer.isOpened():
        pytest.skip("this OpenCV build cannot write PNG-coded AVI files")
    rgb = frames(4)
    for frame in rgb:
        writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
    writer.release()
    return path, rgb


def test_camera_reads_a_video_file_frame_by_frame(video):
    path, rgb = video
    camera = OpenCvCamera(CameraConfig(source=str(path), warmup_frames=0))
    try:
        first = camera.capture("I_disp")
        second = camera.capture("I_macro")
        assert first.dtype == np.uint8 and first.shape == (48, 64, 3)
        assert np.array_equal(first, rgb[0]) and np.array_equal(second, rgb[1])   # RGB, not OpenCV's BGR
        assert "OpenCV" in camera.describe()["camera"]
    finally:
        camera.close()


def test_warmup_frames_are_skipped_and_the_end_is_an_error(video):
    path, rgb = video
    camera = OpenCvCamera(CameraConfig(source=str(path), warmup_frames=2))
    try:
        assert np.array_equal(camera.capture("I_illu"), rgb[2])       # frames 0 and 1 let exposure settle
        assert np.array_equal(camera.capture("I_disp"), rgb[3])       # only one frame was left
        with pytest.raises(DeviceError, match="no frame for I_macro"):
            camera.capture("I_macro")
        with pytest.raises(ValueError, match="'I_side' is not a photo"):
            camera.capture("I_side")
    finally:
        camera.close()


def test_a_camera_announcing_frames_beyond_the_photo_limit_is_refused_before_a_frame_is_read(video, monkeypatch):
    path, _ = video
    monkeypatch.setenv("TEXPLORER_MAX_PHOTO_PIXELS", str(64 * 48 - 1))
    with pytest.raises(DeviceError, match=r"camera '.*tu3.avi': the image has 3,072 pixels \(64 x 48\); at most "
                                          r"3,071 are accepted"):
        OpenCvCamera(CameraConfig(source=str(path), warmup_frames=0))
    monkeypatch.setenv("TEXPLORER_MAX_PHOTO_PIXELS", str(64 * 48))
    camera = OpenCvCamera(CameraConfig(source=str(path), warmup_frames=0))
    assert camera.capture("I_disp").shape == (48, 64, 3)
    camera.close()


def test_uploads_other_than_png_or_jpeg_never_reach_a_decoder():
    bmp = cv2.imencode(".bmp", frames(1, (40, 30))[0])[1].tobytes()  # OpenCV would decode it unchecked
    with pytest.raises(PhotoError, match="upload: not a PNG or JPEG file"):
        decode_photo(bmp)


def test_missing_camera_is_one_line(tmp_path):
    with pytest.raises(DeviceUnavailable, match="cannot be opened") as error:
        OpenCvCamera(CameraConfig(source=str(tmp_path / "none.avi")))
    assert "\n" not in str(error.value)


def test_playback_camera_takes_a_new_set_when_a_photo_is_retaken():
    camera = PlaybackCamera(SimulatedSample("cork-board", seed=2, image_size=(64, 80)))
    first = {name: camera.capture(name) for name in ("I_disp", "I_macro", "I_illu")}
    again = camera.capture("I_disp")
    expected = SimulatedSample("cork-board", seed=2, image_size=(64, 80))
    takes = [expected.photos("x"), expected.photos("x")]
    assert all(np.array_equal(first[name], takes[0][name]) for name in first)
    assert np.array_equal(again, takes[1]["I_disp"]) and not np.array_equal(again, first["I_disp"])
    assert first["I_disp"].shape == (64, 80, 3)


def test_uploaded_png_and_jpeg_decode_to_rgb():
    rgb = frames(1, (40, 30))[0]
    ok, png = cv2.imencode(".png", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    assert ok and np.array_equal(decode_photo(png.tobytes()), rgb)
    flat = np.zeros((32, 32, 3), np.uint8)
    flat[:] = (200, 40, 10)
    ok, jpeg = cv2.imencode(".jpg", cv2.cvtColor(flat, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 100])
    assert np.abs(decode_photo(jpeg.tobytes()).astype(int) - (200, 40, 10)).max() <= 2


@pytest.mark.parametrize(("data", "message"), [
    (b"\x00\x00\x00\x18ftypheic" + b"\x00" * 64, "HEIC photos are not read directly; convert it to PNG"),
    (b"GIF89a" + b"\x00" * 64, "not a PNG or JPEG file"),
    (b"\x89PNG\r\n\x1a\n" + b"\x00" * 64, "the PNG file is damaged"),
])
def test_bad_uploads_are_refused_with_the_reason(data, message):
    with pytest.raises(PhotoError, match=message):
        decode_photo(data, "I_disp")


def test_tiny_and_huge_uploads_are_refused():
    ok, png = cv2.imencode(".png", np.zeros((8, 8, 3), np.uint8))
    with pytest.raises(PhotoError, match="8x8 px is too small"):
        decode_photo(png.tobytes())
    with pytest.raises(PhotoError, match="larger than the 40 MB limit"):
        decode_photo(b"\xff\xd8\xff" + bytes(41 << 20))
