"""sensor_msgs/Image and CompressedImage from OpenCV pictures, shared by the camera and the thermal
imager's live views."""
import rospy
from sensor_msgs.msg import CompressedImage, Image

from inspection_robot.camera.jpeg import COMPRESSED_SUFFIX, JPEG_FORMAT, check_quality, encode_jpeg


def bgr_image_msg(img, stamp, frame_id):
    """A bgr8 Image of an HxWx3 uint8 picture."""
    msg = Image(height=img.shape[0], width=img.shape[1], encoding="bgr8", is_bigendian=0,
                step=img.shape[1] * 3, data=img.tobytes())
    msg.header.stamp, msg.header.frame_id = stamp, frame_id
    return msg


class LiveViewPublisher(object):
    """``<topic>`` (bgr8 Image) and ``<topic>/compressed`` (JPEG CompressedImage, as image_transport
    names it); each is built only while it has subscribers, so an idle robot encodes nothing."""

    def __init__(self, topic, jpeg_quality):
        self._quality = check_quality(jpeg_quality)
        self._raw = rospy.Publisher(topic, Image, queue_size=1)
        self._jpeg = rospy.Publisher(topic + COMPRESSED_SUFFIX, CompressedImage, queue_size=1)

    def wanted(self):
        """True while someone subscribes to either form."""
        return self._raw.get_num_connections() > 0 or self._jpeg.get_num_connections() > 0

    def publish(self, img, stamp, frame_id):
        if self._raw.get_num_connections() > 0:
            self._raw.publish(bgr_image_msg(img, stamp, frame_id))
        if self._jpeg.get_num_connections() > 0:
            msg = CompressedImage(format=JPEG_FORMAT, data=encode_jpeg(img, self._quality))
            msg.header.stamp, msg.header.frame_id = stamp, frame_id
            self._jpeg.publish(msg)
