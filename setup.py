# Installed by catkin_python_setup(); do not run directly.
# Only the robot's package: src/inspection_robot_testing (the test harness) is never installed
# (CMakeLists.txt makes it importable in the devel space only).
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import find_packages, setup

setup(**generate_distutils_setup(packages=find_packages("src", include=["inspection_robot", "inspection_robot.*"]),
                                 package_dir={"": "src"}))
