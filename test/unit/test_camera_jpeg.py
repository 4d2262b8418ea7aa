"""camera.jpeg: the live views' JPEG frames (what <image topic>/compressed carries)."""
import cv2
import numpy as np
import pytest

from inspection_robot.camera.jpeg import check_quality, encode_jpeg


def test_a_picture_comes_back_from_its_jpeg_and_quality_sets_the_size():
    img = np.zeros((48, 64, 3), np.uint8)
    img[:, 32:] = (0, 0, 255)   # right half red (bgr)
    img[:8:2, ::2, 1] = 255     # fine detail at the top: a higher quality keeps more of it
    high, low = encode_jpeg(img, 95), encode_jpeg(img, 20)
    assert high[:2] == b"\xff\xd8" and len(low) < len(high)
    back = cv2.imdecode(np.frombuffer(high, np.uint8), cv2.IMREAD_COLOR)
    assert back.shape == (48, 64, 3) and back[24, 50, 2] > 200 and back[24, 10, 2] < 50
    grey = cv2.imdecode(np.frombuffer(encode_jpeg(img[:, :, 2], 90), np.uint8), cv2.IMREAD_UNCHANGED)
    assert grey.shape == (48, 64)


@pytest.mark.parametrize("img", [np.zeros((4, 4, 4), np.uint8), np.zeros((4, 4, 3), np.float32),
                                 np.zeros((0, 4, 3), np.uint8)])
def test_pictures_jpeg_cannot_hold_are_refused(img):
    with pytest.raises(ValueError, match="cannot encode"):
        encode_jpeg(img, 80)


@pytest.mark.parametrize("quality", [-1, 101, "80", True, None])
def test_a_quality_outside_0_100_is_refused(quality):
    with pytest.raises(ValueError, match="JPEG quality must be a number in 0..100"):
        check_quality(quality)
    assert check_quality(80.0) == 80
