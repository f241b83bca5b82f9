#!/usr/bin/env bash
# Runs a command on a private Xvfb of its own: Xvfb picks a free display number itself
# (-displayfd), so that tests running side by side never share, or race for, an X server (xvfb-run -a
# picks a number by looking for lock files, and two at once can pick the same one).
# Usage: with-xvfb.sh WIDTHxHEIGHTxDEPTH COMMAND [ARGS...]
set -euo pipefail
screen="$1"
shift
fifo_dir="$(mktemp -d)"
trap 'rm -rf "$fifo_dir"' EXIT
mkfifo "$fifo_dir/fd"
Xvfb -displayfd 3 -screen 0 "$screen" -nolisten tcp -noreset 3> "$fifo_dir/fd" 2> "$fifo_dir/log" &
xvfb=$!
trap 'kill "$xvfb" 2> /dev/null; wait "$xvfb" 2> /dev/null; rm -rf "$fifo_dir"' EXIT
number=""
read -r -t 30 number < "$fifo_dir/fd" || true
if [ -z "$number" ]; then
  echo "with-xvfb.sh: Xvfb did not start: $(cat "$fifo_dir/log")" >&2
  exit 1
fi
export DISPLAY=":$number"
unset XAUTHORITY
status=0
"$@" || status=$?
exit $status
