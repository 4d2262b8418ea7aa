"""JPEG frames of the live views, as image_transport's ``compressed`` plug-in names and encodes them.

The camera and the thermal imager publish each live picture also as sensor_msgs/CompressedImage
(``format`` "jpeg") on ``<image topic>/compressed``: a console or a recorder gets ~50 kB instead of
~1 MB of raw pixels per frame, and the robot encodes it once for every subscriber.
"""
import numpy as np

from inspection_robot.lazy import lazy_import

cv2 = lazy_import("cv2")   # on first use: camera_node and infrared_imager import this before they register

COMPRESSED_SUFFIX = "/compressed"  # image_transport's topic name of the compressed plug-in
# CompressedImage.format (image_transport's plug-in writes "bgr8; jpeg compressed bgr8"; a browser needs neither)
JPEG_FORMAT = "jpeg"


def check_quality(quality):
    """``quality`` as an int in 0..100; ValueError otherwise."""
    if isinstance(quality, bool) or not isinstance(quality, (int, float)) or not 0 <= quality <= 100:
        raise ValueError("JPEG quality must be a number in 0..100, not %r" % (quality,))
    return int(quality)


def encode_jpeg(img, quality):
    """JPEG bytes of an HxWx3 (BGR) or HxW uint8 picture at ``quality`` (0..100)."""
    img = np.asarray(img)
    if img.dtype != np.uint8 or img.ndim not in (2, 3) or (img.ndim == 3 and img.shape[2] != 3) or not img.size:
        raise ValueError("cannot encode a %s %s array as JPEG (HxWx3 or HxW uint8)" % (img.dtype, img.shape))
    ok, buf = cv2.imencode(".jpg", img, [int(cv2.IMWRITE_JPEG_QUALITY), check_quality(quality)])
    if not ok:
        raise ValueError("JPEG encoding failed for a %dx%d picture" % (img.shape[1], img.shape[0]))
    return buf.tobytes()
