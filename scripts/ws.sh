# Sourced by scripts/build, scripts/rosenv and scripts/test: where the hidden catkin workspace lives.
# It sits outside the package tree (under the user's cache directory, one per checkout), because a
# workspace inside the package makes the package contain itself: rosrun's `find -L` then sees every
# executable twice. INSPECTION_ROBOT_WS names another workspace (e.g. a catkin workspace this
# repository was cloned into). Expects $root (the repository root) to be set.
if [ -n "${INSPECTION_ROBOT_WS:-}" ]; then
  ws="$INSPECTION_ROBOT_WS"
else
  ws="${XDG_CACHE_HOME:-$HOME/.cache}/inspection_robot/ws-$(printf '%s' "$root" | sha256sum | cut -c1-12)"
fi
