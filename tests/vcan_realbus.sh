# Runs inside the vcan sandbox (tests/test_can_realbus.py): the README's real-bus commands,
# exactly as written, each in its own folder under OUT_DIR (railguard writes railguard-out/ there).
#
# Usage: sh tests/vcan_realbus.sh OUT_DIR
#   OUT_DIR/monitor/: `railguard run --interface socketcan --channel vcan0 --no-player`, interrupted
#                     with SIGINT about 4 s after its first status line
#   OUT_DIR/player/:  `railguard run --interface socketcan --channel vcan0 --duration 3`
# Each folder gets stdout, stderr and rc. A non-interactive sh starts background jobs with
# SIGINT ignored; the monitor installs its own handler, so SIGINT must still end it.
set -u
OUT=$1

mkdir -p "$OUT/monitor" "$OUT/player"
cd "$OUT/monitor"
railguard run --interface socketcan --channel vcan0 --no-player > stdout 2> stderr &
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
railguard run --interface socketcan --channel vcan0 --duration 3 > stdout 2> stderr
echo $? > rc
echo "monitor_rc=$(cat "$OUT/monitor/rc") player_rc=$(cat "$OUT/player/rc")"
