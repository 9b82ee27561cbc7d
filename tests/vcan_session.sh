# Runs inside the vcan sandbox (tests/test_socketcan.py): candump records the bus while the
# monitor and the scenario player run as two separate processes on the real vcan0.
# Usage: sh tests/vcan_session.sh OUT_DIR SCENARIO.toml
set -u
OUT=$1
SCEN=$2
candump -L vcan0 > "$OUT/bus.log" &
CD=$!
python -m railguard run --interface socketcan --channel vcan0 --no-player --unsecured --table m1 --duration 90 \
    --json --no-plot --quiet --out "$OUT" > "$OUT/monitor.json" 2> "$OUT/monitor.err" &
MON=$!
python -m railguard play "$SCEN" --interface socketcan --channel vcan0 --unsecured --json > "$OUT/player.json" 2> "$OUT/player.err"
PLAYER_RC=$?
kill -TERM $MON
wait $MON
MONITOR_RC=$?
sleep 0.3
kill $CD
echo "player_rc=$PLAYER_RC monitor_rc=$MONITOR_RC"
[ $PLAYER_RC -eq 0 ] && [ $MONITOR_RC -eq 0 ]
