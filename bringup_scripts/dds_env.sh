# Sourced by ost_up.sh and tests/run.sh: how OST processes talk DDS on this host (docs/ros.md,
# "Transport"). Everything stays on the loopback interface, over UDP: the default profile
# fastdds_localhost_udp.xml whitelists 127.0.0.1 and turns Fast DDS's shared-memory transport off.
# rmw_fastrtps switches shared memory back on under ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST, so
# with our profile the range is SUBNET — a subnet that is the loopback interface alone. A user who
# sets FASTRTPS_DEFAULT_PROFILES_FILE to a profile of their own keeps full control (and the usual
# LOCALHOST default applies).
_ost_profile="$(cd "$(dirname "${BASH_SOURCE[0]}")/../ost_ros/dds" && pwd -P)/fastdds_localhost_udp.xml"
if [ -z "${FASTRTPS_DEFAULT_PROFILES_FILE:-}" ] || [ "$FASTRTPS_DEFAULT_PROFILES_FILE" = "$_ost_profile" ]; then
  export FASTRTPS_DEFAULT_PROFILES_FILE="$_ost_profile"
  export ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET
else
  export ROS_AUTOMATIC_DISCOVERY_RANGE="${ROS_AUTOMATIC_DISCOVERY_RANGE:-LOCALHOST}"
fi
unset _ost_profile
