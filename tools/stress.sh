#!/bin/sh
# The suite beside two CPU hogs: what `make test` meets on a busy machine.
# Each hog is a Python loop at full speed, started before the suite and
# killed after it, whatever the suite's end; the suite's exit code is kept.
#     sh tools/stress.sh PYTHON [PYTEST ARGS...]
set -u
py="$1"
shift
"$py" -c "while True: pass" &
hog1=$!
"$py" -c "while True: pass" &
hog2=$!
trap 'kill "$hog1" "$hog2" 2>/dev/null' EXIT INT TERM
echo "stress: two CPU hogs (pids $hog1 $hog2) beside the suite"
"$py" -m pytest "$@"
