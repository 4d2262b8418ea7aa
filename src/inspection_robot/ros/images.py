"""sensor_msgs/Image from OpenCV pictures, shared by the camera and the thermal imager's live views."""
from sensor_msgs.msg import Image


def bgr_image_msg(img, stamp, frame_id):
    """A bgr8 Image of an HxWx3 uint8 picture."""
    msg = Image(height=img.shape[0], width=img.shape[1], encoding="bgr8", is_bigendian=0,
                step=img.shape[1] * 3, data=img.tobytes())
    msg.header.stamp, msg.header.frame_id = stamp, frame_id
    return msg
