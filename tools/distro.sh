# Sourced by tools/setup.sh and tools/run.sh: which ROS 2 distribution this shell builds and runs against.
#   ROS_DISTRO=kilted (default): requirements.lock,        .venv,        ros_ws/{build,install,log}
#   ROS_DISTRO=jazzy:            requirements-jazzy.lock,  .venv-jazzy,  ros_ws/{build,install,log}-jazzy
# Both can be set up side by side; nothing in ros_ws/src depends on the choice.
# Sets DISTRO, LOCK, VENV, WS_BUILD, WS_INSTALL, WS_LOG (absolute paths; ROOT must be set).
DISTRO=${ROS_DISTRO:-kilted}
case "$DISTRO" in
  kilted) suffix="" ; LOCK=$ROOT/requirements.lock ;;
  jazzy)  suffix="-jazzy" ; LOCK=$ROOT/requirements-jazzy.lock ;;
  *) echo "ROS_DISTRO=$DISTRO: this project is set up against kilted (default) or jazzy;" \
          "unset ROS_DISTRO or pass ROS_DISTRO=kilted|jazzy" >&2
     return 1 2>/dev/null || exit 1 ;;
esac
VENV=$ROOT/.venv$suffix
WS_BUILD=$ROOT/ros_ws/build$suffix
WS_INSTALL=$ROOT/ros_ws/install$suffix
WS_LOG=$ROOT/ros_ws/log$suffix
unset suffix
