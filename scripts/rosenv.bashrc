# rc file of the interactive shell `scripts/rosenv bash` (make shell): the user's own ~/.bashrc, then
# rosbash's shell functions (roscd, rosls, rosed...), which Debian ships as bash completion and
# Noetic under /opt/ros (its setup.bash already sources them there).
# shellcheck disable=SC1090,SC1091
[ -f "$HOME/.bashrc" ] && . "$HOME/.bashrc"
if ! type roscd > /dev/null 2>&1; then
  for f in /opt/ros/noetic/share/rosbash/rosbash /usr/share/bash-completion/completions/rosbash; do
    if [ -f "$f" ]; then . "$f"; break; fi
  done
fi
