"""Command-line tools of the robot (run by name through scripts/rosenv, or with rosrun): their
executables live in the repository's tools/ folder, their code here.
"""
