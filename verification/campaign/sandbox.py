"""A few sessions on real SocketCAN vcan0 in the user-mode-Linux sandbox: the plan, the guest
side (`python -m verification.campaign --vcan-guest`: the monitor and the Player on vcan0,
wall clock, one JSON file per session) and the host side (boot once, judge every session).
"""
from __future__ import annotations

import json
import shlex
import sys
import tempfile
import time
import traceback
from pathlib import Path
from typing import Optional

from monitor.core import cycle
from monitor.core.config import Config

from ..report import Progress
from .bus import BusSpec, bus_scenario, counting_core
from .judge import bus_detection, evaluate_bus
from .specs import Fault
from .tables import shipped_table


VCAN_SCENARIO = "static-300m-20"


def vcan_plan(quick: bool) -> list[BusSpec]:
    kinds = (("silence", 2), ("bad_crc", 0), ("babble", 3), ("counter_jump", 4), ("contradiction", 1))
    specs = [BusSpec(f"vcan-{k}", VCAN_SCENARIO, (Fault(k, ch, 1.5, 3.5, (20,) if k == "babble" else ()),),
                     ("m1", "m2")[i % 2], 40 + i, True, 9.0) for i, (k, ch) in enumerate(kinds)]
    return specs[:1] if quick else specs


def vcan_guest(spec_path: str, out_dir: str) -> int:
    """Runs inside the sandbox: each session is the monitor (MonitorRunner, wall clock) and
    the Player (in a thread, as `railguard run` does) on the real SocketCAN vcan0; writes one
    JSON file per session."""
    import threading

    import can

    from can_bus.clock import WallClock
    from can_bus.player import Player
    from can_bus.runner import MonitorRunner

    from can_bus.codec import Receiver, Sender, database

    specs = json.loads(Path(spec_path).read_text())
    cfg = Config(**specs[0]["config"]) if specs else Config()
    out = Path(out_dir)
    # warm up (parse the DBC, encode and check every message once, build the setups) so that
    # the first session does not start with a cold process, as a deployed monitor would not
    rx, tx = Receiver(rate_window_ms=0), Sender()
    for msg in database().messages:
        rx.accept(msg.frame_id, tx.frame(msg.frame_id, {}), 0)
    for raw in specs:
        cycle.create(cfg, shipped_table(raw["model"]))
    bus_kwargs = {"interface": "socketcan", "channel": "vcan0"}
    for i, raw in enumerate(specs):
        spec = BusSpec(raw["name"], raw["scenario"], tuple(Fault(*f[:4], tuple(f[4])) for f in raw["faults"]),
                       raw["model"], raw["seed"], raw["detection"], raw["duration_s"])
        result = {"name": spec.name}
        counter, restore = counting_core()
        try:
            scen = bus_scenario(spec, cfg)
            setup = cycle.create(cfg, shipped_table(spec.model))
            clock = WallClock()
            mon_bus, player_bus = can.Bus(**bus_kwargs), can.Bus(**bus_kwargs)
            stop = threading.Event()
            player = Player(player_bus, scen, setup.config.period_ms)
            steps: list = []

            def play() -> None:
                tick = clock.now_ms()
                while not stop.is_set() and not player.finished:
                    clock.sleep_until_ms(tick)
                    player.step(tick)
                    steps.append(tick)
                    tick += player.period_ms

            try:
                runner = MonitorRunner(mon_bus, setup, clock)
                thread = threading.Thread(target=play, daemon=True)
                thread.start()
                limit = int((scen.duration_s + 10) * 1000 / setup.config.period_ms)
                for _ in range(limit):
                    runner.drain(runner.next_tick)
                    clock.sleep_until_ms(runner.next_tick)
                    runner.cycle()
                    if player.finished:
                        break
                stop.set()
                runner.send_final_emergency()
                thread.join(timeout=2)
            finally:
                mon_bus.shutdown()
                player_bus.shutdown()
            n = min(len(steps), len(player.trace))
            result.update(
                records=[[r.tick, r.demand, r.reasons, r.mode, r.node, r.distance_dm, r.module_flags, r.system_error,
                          r.speed_cms, r.warning] for r in runner.records],
                trace=[[row.t_s, row.speed_mps, row.distance_m] for row in player.trace[:n]], trace_ticks=steps[:n],
                outcome=player.outcome(), collision=player.collision, entered=player.started,
                rejects=dict(runner.receiver.rejected), deadline_misses=runner.deadline_misses,
                frames_received=runner.frames_received, core_exceptions=counter[0],
                faults_injected=sorted(f"{k}@ch{c}" for k, c in player.faults_injected))
        except Exception as exc:  # noqa: BLE001 - reported to the host as the session's crash
            result["error"] = f"{type(exc).__name__}: {exc}\n{traceback.format_exc(limit=6)}"
        finally:
            restore()
        (out / f"session-{i}.json").write_text(json.dumps(result))
    return 0


def vcan_sample(specs: list[BusSpec], progress: Progress, config: Optional[Config] = None, margin_m: float = 0.0) -> dict:
    """Boot the sandbox once and run every session in it (the world's train: the
    declaration's worst corner); evaluate them on the host."""
    cfg = config or Config()
    from can_bus import vcan
    from can_bus.runner import CycleRecord

    root = Path(__file__).resolve().parents[2]       # the checkout: verification/campaign/ is two below
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="railguard-campaign-vcan-") as tmp:
        spec_path = Path(tmp) / "sessions.json"
        spec_path.write_text(json.dumps([{"name": s.name, "scenario": s.scenario, "model": s.model, "seed": s.seed,
                                          "detection": s.detection, "duration_s": s.duration_s, "config": cfg._asdict(),
                                          "faults": [[f.kind, f.channel, f.start_s, f.end_s, list(f.variant)]
                                                     for f in s.faults]} for s in specs]))
        script = Path(tmp) / "sessions.sh"
        script.write_text("set -u\n" + f"{shlex.quote(sys.executable)} -m verification.campaign --vcan-guest "
                          f"{shlex.quote(str(spec_path))} {shlex.quote(tmp)}\n")
        budget = 40.0 + sum((s.duration_s or 20.0) + 6.0 for s in specs)
        progress(f"campaign: {len(specs)} session(s) on vcan0 in the user-mode-Linux sandbox (up to {budget:.0f} s)")
        res = vcan.run(["sh", str(script)], timeout=budget, cwd=root, env={"PYTHONPATH": str(root)})
        runs = []
        for i, spec in enumerate(specs):
            p = Path(tmp) / f"session-{i}.json"
            if not p.exists():
                runs.append({"name": spec.name, "kinds": spec.kinds, "crash": "session did not finish "
                             f"(timed out: {res.timed_out}; stderr: {res.stderr.strip()[-300:]})", "unsafe": 0,
                             "collision": False, "false_braking": False, "detected": {}})
                continue
            raw = json.loads(p.read_text())
            run = {"name": spec.name, "kinds": spec.kinds, "scenario": spec.scenario, "model": spec.model,
                   "crash": raw.get("error"), "unsafe": 0, "collision": False, "false_braking": False, "detected": {}}
            if "records" in raw:
                records = [CycleRecord(*r) for r in raw["records"]]
                run.update(evaluate_bus(records, [tuple(x) for x in raw["trace"]], raw["trace_ticks"], spec.scenario,
                                        margin_m))
                run.update(raw["outcome"], collision=raw["collision"], entered=raw["entered"], rejects=raw["rejects"],
                           deadline_misses=raw["deadline_misses"], frames_received=raw["frames_received"],
                           faults_injected=raw["faults_injected"])
                run["detected"] = bus_detection(spec.faults, records, raw["rejects"])
                problems = [run["crash"]] if run["crash"] else []
                if raw["core_exceptions"]:
                    problems.append(f"{raw['core_exceptions']} exception(s) inside the core")
                if raw["rejects"].get("undecodable"):
                    problems.append(f"{raw['rejects']['undecodable']} exception(s) in the receive path")
                run["crash"] = "; ".join(problems) or None
            runs.append(run)
    return {"runs": runs, "seconds": time.perf_counter() - t0, "timed_out": res.timed_out,
            "returncode": res.returncode}
