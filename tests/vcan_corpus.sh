# Runs inside the vcan sandbox (tests/test_log_corpus.py): hostile corpus logs played with
# can-utils' canplayer on real SocketCAN buses while `railguard run` monitors each of them.
#
# Usage: sh tests/vcan_corpus.sh OUT_DIR FILE.log...
#   The i-th FILE (0-based; recorded on vcan0, its recorded-monitor lines already removed by
#   the caller) is played on vcanI (vcan0 exists; vcan1, vcan2, ... are created here), all
#   at the same time, each bus with its own monitor, so that the session takes one file's
#   length instead of their sum. For each: start the monitor, wait until its first
#   BrakeDemand is on its bus (candump -n 1 exits then), play FILE with its own timing
#   (canplayer vcanI=vcan0), give the monitor 0.5 s more, then SIGTERM (it ends with a last
#   emergency demand and its JSON summary).
# Writes OUT_DIR/NAME/monitor.json, monitor.err, canplayer.err, canplayer.rc, rc and prints one
# line per file. Exit status: 0 if every monitor exited 0.
set -u
OUT=$1
shift

i=0
for f in "$@"; do
    name=$(basename "$f" .log)
    dir="$OUT/$name"
    mkdir -p "$dir"
    bus=vcan$i
    if [ $i -gt 0 ]; then
        ip link add dev $bus type vcan && ip link set up $bus || echo "$bus could not be created" >&2
    fi
    echo $bus > "$dir/bus"
    candump -n 1 $bus,010:7FF > "$dir/first.txt" 2> /dev/null &
    echo $! > "$dir/candump.pid"
    railguard run --interface socketcan --channel $bus --no-player --unsecured --json --quiet --no-plot --duration 60 \
        --out "$dir" > "$dir/monitor.json" 2> "$dir/monitor.err" &
    echo $! > "$dir/monitor.pid"
    i=$((i + 1))
done

# every monitor is up once its first BrakeDemand is on its bus (python starts slowly in here)
for f in "$@"; do
    dir="$OUT/$(basename "$f" .log)"
    CD=$(cat "$dir/candump.pid")
    MON=$(cat "$dir/monitor.pid")
    n=0
    while kill -0 $CD 2> /dev/null; do
        n=$((n + 1))
        if [ $n -gt 1500 ] || ! kill -0 $MON 2> /dev/null; then
            echo "$(basename "$f" .log): monitor did not start" >&2
            kill $CD 2> /dev/null
            break
        fi
        sleep 0.02
    done
    wait $CD 2> /dev/null
done

PLAYERS=""
for f in "$@"; do
    dir="$OUT/$(basename "$f" .log)"
    ( canplayer -I "$f" "$(cat "$dir/bus")=vcan0" > /dev/null 2> "$dir/canplayer.err"; echo $? > "$dir/canplayer.rc" ) &
    PLAYERS="$PLAYERS $!"
done
for p in $PLAYERS; do wait $p; done
sleep 0.5

STATUS=0
for f in "$@"; do
    name=$(basename "$f" .log)
    dir="$OUT/$name"
    MON=$(cat "$dir/monitor.pid")
    kill -TERM $MON 2> /dev/null
    wait $MON
    rc=$?
    echo $rc > "$dir/rc"
    [ $rc -eq 0 ] || STATUS=1
    echo "$name on $(cat "$dir/bus"): monitor_rc=$rc canplayer_rc=$(cat "$dir/canplayer.rc")"
done
exit $STATUS
