#!/usr/bin/env bash
# Simulated hosts on one machine: K network namespaces, each with its own IP on one Linux bridge
# (the bridge sits in a namespace of its own, so the root namespace is untouched). Needs root.
#
#   bringup_scripts/sim_hosts.sh up NAME K [--net N] [--loss PCT] [--block-multicast]
#   bringup_scripts/sim_hosts.sh down NAME
#
# up: hosts NAME_h0 .. NAME_h{K-1} with addresses 10.77.N.1 .. 10.77.N.K (/24); prints them, one
# per line. --loss PCT drops PCT % of every packet a host sends (nftables `numgen random`, inside
# the host namespace); --block-multicast drops multicast (224.0.0.0/4) on the bridge, so DDS
# discovery needs ROS_STATIC_PEERS or a discovery server. down: deletes NAME's namespaces.
# Run a command on host i with `ip netns exec NAME_h<i> COMMAND`.
set -euo pipefail
me="sim_hosts"
die() { echo "$me: error: $*" >&2; exit 2; }
[ $# -ge 2 ] || die "usage: sim_hosts.sh up NAME K [--net N] [--loss PCT] [--block-multicast] | down NAME"
cmd="$1" name="$2"
[[ "$name" =~ ^[A-Za-z0-9_]{1,20}$ ]] || die "NAME: letters, digits and _ only (1-20), got '$name'"
[ "$(id -u)" = 0 ] || die "simulated hosts need root (network namespaces)"
command -v ip >/dev/null || die "ip (iproute2) not found"

down() {
  for ns in $(ip netns list 2>/dev/null | awk '{print $1}' | grep -E "^${name}_(sw|h[0-9]+)$" || true); do
    ip netns del "$ns" 2>/dev/null || true
  done
}

case "$cmd" in
  down) down; exit 0 ;;
  up) ;;
  *) die "unknown command '$cmd' (up or down)" ;;
esac
[ $# -ge 3 ] || die "up needs K (the number of hosts)"
k="$3"; shift 3
[[ "$k" =~ ^[0-9]+$ ]] && [ "$k" -ge 1 ] && [ "$k" -le 250 ] || die "K: 1..250, got '$k'"
net=77 loss=0 block=0
while [ $# -gt 0 ]; do
  case "$1" in
    --net) [[ "${2:-}" =~ ^[0-9]+$ ]] && [ "$2" -le 255 ] || die "--net: 0..255"; net="$2"; shift 2 ;;
    --loss) [[ "${2:-}" =~ ^[0-9]+$ ]] && [ "$2" -le 100 ] || die "--loss: a percentage 0..100"; loss="$2"; shift 2 ;;
    --block-multicast) block=1; shift ;;
    *) die "unknown argument '$1'" ;;
  esac
done
if [ "$loss" -gt 0 ] || [ "$block" = 1 ]; then
  command -v nft >/dev/null || die "nft not found (Debian package nftables) for --loss / --block-multicast"
fi
down   # a previous set of the same name
trap 'down' ERR
sw="${name}_sw"
ip netns add "$sw"
ip netns exec "$sw" ip link add br0 type bridge
ip netns exec "$sw" ip link set br0 up
if [ "$block" = 1 ]; then
  ip netns exec "$sw" nft -f - <<EOF
table bridge ost {
  chain forward { type filter hook forward priority 0; ip daddr 224.0.0.0/4 drop; }
}
EOF
fi
for i in $(seq 0 $((k - 1))); do
  h="${name}_h$i"
  ip netns add "$h"
  ip netns exec "$sw" ip link add "p$i" type veth peer name eth0 netns "$h"
  ip netns exec "$sw" ip link set "p$i" master br0 up
  ip netns exec "$h" ip link set lo up
  ip netns exec "$h" ip addr add "10.77.$net.$((i + 1))/24" dev eth0
  ip netns exec "$h" ip link set eth0 up
  ip netns exec "$h" ip route add default dev eth0      # multicast (discovery) goes out on eth0
  if [ "$loss" -gt 0 ]; then
    ip netns exec "$h" nft -f - <<EOF
table inet ost {
  chain output { type filter hook output priority 0; oifname "eth0" numgen random mod 100 < $loss drop; }
}
EOF
  fi
  echo "10.77.$net.$((i + 1))"
done
trap - ERR
