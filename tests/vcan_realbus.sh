# Runs inside the vcan sandbox (tests/test_can_realbus.py): the README's real-bus commands,
# exactly as written, each in its own folder under OUT_DIR (railguard writes railguard-out/ there).
#
# Usage: sh tests/vcan_realbus.sh OUT_DIR
#   OUT_DIR/hil-keys: `railguard keys new hil-keys`, the key set every command below uses (--keys)
#   OUT_DIR/monitor/: `railguard run --interface socketcan --channel vcan0 --keys hil-keys --no-player`, interrupted
#                     with SIGINT about 4 s after its first status line
#   OUT_DIR/player/:  `railguard run --interface socketcan --channel vcan0 --keys hil-keys --duration 3`
#   OUT_DIR/kill/:    the monitor (`railguard run ... --no-player`) and `railguard play` of a
#                     10 m/s clear-track world as two processes; the monitor is killed with
#                     SIGKILL 3 s after the train entered: the player's brake receiver must
#                     brake on the silence (issue 39) and the train stand
# Each folder gets stdout, stderr and rc. A non-interactive sh starts background jobs with
# SIGINT ignored; the monitor installs its own handler, so SIGINT must still end it.
set -u
OUT=$1
# the README's key set (a real bus is secured: railguard keys new DIR, then --keys DIR)
(cd "$OUT" && railguard keys new hil-keys > keys.stdout 2> keys.stderr)
KEYS="$OUT/hil-keys"

mkdir -p "$OUT/monitor" "$OUT/player"
cd "$OUT/monitor"
railguard run --interface socketcan --channel vcan0 --keys "$KEYS" --no-player > stdout 2> stderr &
MON=$!
# SIGINT only once the monitor runs (before its handler is installed, SIGINT is ignored here)
i=0
while ! grep -q "demand" stderr 2>/dev/null && kill -0 $MON 2>/dev/null && [ $i -lt 400 ]; do
    i=$((i + 1)); sleep 0.1
done
sleep 4
kill -INT $MON
# it must end by itself: a last emergency demand, the summary (and the plot); else SIGKILL
i=0
while kill -0 $MON 2>/dev/null && [ $i -lt 400 ]; do i=$((i + 1)); sleep 0.1; done
kill -0 $MON 2>/dev/null && { echo "still running 40 s after SIGINT: SIGKILL" >> stderr; kill -KILL $MON; }
wait $MON
echo $? > rc

cd "$OUT/player"
railguard run --interface socketcan --channel vcan0 --keys "$KEYS" --duration 3 > stdout 2> stderr
echo $? > rc

mkdir -p "$OUT/kill"
cd "$OUT/kill"
cat > kill-world.toml <<'TOML'
description = "clear track, 10 m/s: the monitor is killed under way"
duration_s = 15.0
[train]
speed_mps = 10.0
TOML
railguard run --interface socketcan --channel vcan0 --keys "$KEYS" --no-player > monitor.stdout 2> monitor.stderr &
MON=$!
railguard play kill-world.toml --interface socketcan --channel vcan0 --keys "$KEYS" --json > stdout 2> stderr &
PLAY=$!
# the train enters once the monitor reports NORMAL with no demand: wait for its status line, then 3 s
i=0
while ! grep -q "mode NORMAL" monitor.stderr 2>/dev/null && [ $i -lt 300 ]; do i=$((i + 1)); sleep 0.1; done
sleep 3
kill -KILL $MON
date +%s.%N > killed_at
wait $PLAY
echo $? > rc
echo "monitor_rc=$(cat "$OUT/monitor/rc") player_rc=$(cat "$OUT/player/rc") play_rc=$(cat "$OUT/kill/rc")"
