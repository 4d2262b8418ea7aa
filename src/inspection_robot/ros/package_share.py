"""The installed (or devel-space) share directory of this package, through rospkg (tools/ imports no ROS)."""
import os


def share_file(*parts):
    """Path of ``parts`` under inspection_robot's share directory; None when ROS cannot find the package."""
    try:
        import rospkg
        return os.path.join(rospkg.RosPack().get_path("inspection_robot"), *parts)
    except Exception:  # boundary: no ROS package path (rospkg missing or the package not on ROS_PACKAGE_PATH)
        return None
