"""The one scenario language (issue 15): the loader's refusals, the catalogue (every file
loads, every player that claims it plays it accepts it, one name one world), the players'
refusals in one line, and docs/scenarios.md listing every shipped scenario."""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from monitor.tables import DEFAULT as DEFAULT_TABLE
from monitor import scenario as sc

ROOT = Path(__file__).resolve().parents[1]
CATALOGUE = sc.catalogue()
NAMES = [e.name for e in CATALOGUE]


def write(tmp_path: Path, text: str, name: str = "mine.toml") -> str:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return str(path)


def refused(path: str, match: str, error=sc.ScenarioError) -> str:
    with pytest.raises(error, match=match) as exc:
        sc.load(path)
    message = str(exc.value)
    assert "\n" not in message and message.startswith(path + ": "), message
    return message


# ----------------------------------------------------------------------------- the loader

@pytest.mark.parametrize("text,match", [
    ("wheels = 4\n", "unknown key.*wheels"),
    ("[train]\nwheels = 4\n", "train: unknown key.*wheels"),
    ("[sensors]\nrange = 400.0\n", "sensors: unknown key.*range"),
    ("[[obstacles]]\nposition = 400.0\n", r"obstacles\[0\]: unknown key.*position"),
    ("[[faults]]\nkind = 'silence'\nchannel = 1\nstart_s = 1.0\nstop_s = 2.0\n", r"faults\[0\]: unknown key.*stop_s"),
    ("[monitor]\nemergency_decel = 2400\n", "monitor: unknown key.*emergency_decel"),
    ("[campaign]\nseeds = 3\n", "campaign: unknown key.*seeds"),
])
def test_unknown_keys_are_refused(tmp_path, text, match):
    refused(write(tmp_path, text), match)


@pytest.mark.parametrize("text,match", [
    ("duration_s = 'long'\n", "duration_s.*a number"),
    ("description = 3\n", "description.*a string"),
    ("[train]\nspeed_mps = 'fast'\n", "train.speed_mps.*a number"),
    ("[train]\nspeed_mps = true\n", "train.speed_mps.*a number"),
    ("[sensors]\nseed = 1.5\n", "sensors.seed.*whole number"),
    ("[[faults]]\nkind = 'silence'\nchannel = 1.0\nstart_s = 1.0\n", r"faults\[0\].channel.*whole number"),
    ("[monitor]\ntimeout_cycles = 3.0\n", "monitor.timeout_cycles.*whole number"),
    ("obstacles = 3\n", "obstacles.*array of tables"),
    ("train = 3\n", "train.*must be a table"),
    ("[train]\ntrack = 'icy'\n", "train.track = 'icy'.*normal, slippery"),
    ("[[obstacles]]\ntype = 'cow'\n", r"obstacles\[0\].type = 'cow'"),
    ("[[obstacles]]\nleave_s = 'soon'\n", r"obstacles\[0\].leave_s.*a number"),
    ("[[faults]]\nkind = 'gremlins'\nchannel = 1\nstart_s = 1.0\n", "gremlins"),
])
def test_wrong_types_are_refused(tmp_path, text, match):
    refused(write(tmp_path, text), match)


@pytest.mark.parametrize("text,match", [
    ("duration_s = 0.0\n", r"duration_s = 0.0: must be in \(0"),
    ("demand_delay_cycles = -1\n", "demand_delay_cycles = -1"),
    ("[train]\nspeed_mps = 130.0\n", "train.speed_mps = 130.0"),
    ("[train]\ngradient_permille = -70\n", "train.gradient_permille = -70"),
    ("[train]\nservice_decel_mps2 = 4.0\n", "service_decel_mps2 = 4 exceeds an emergency deceleration"),
    ("[train]\nemergency_decel_mps2 = [[10.0, 2.4]]\n", "bands start at 0 m/s"),
    ("[sensors]\nmiss_probability = 1.0\n", "miss_probability"),
    ("[sensors]\nrange_m = 0\n", "sensors.range_m = 0"),
    ("[[faults]]\nkind = 'silence'\nchannel = 6\nstart_s = 1.0\n", r"faults\[0\].channel = 6"),
    ("[[obstacles]]\nleave_s = -1.0\n", r"obstacles\[0\].leave_s = -1.0: must be in \[0, 1e\+09\]"),
    ("[[obstacles]]\nleave_s = 2e9\n", r"obstacles\[0\].leave_s = 2000000000.0: must be in"),
    ("[[obstacles]]\nleave_s = inf\n", r"obstacles\[0\].leave_s.*finite"),
    ("[[obstacles]]\nappear_s = 5.0\nleave_s = 5.0\n", r"obstacles\[0\].leave_s = 5: must be after appear_s = 5"),
    ("[[obstacles]]\nposition_m = 400\n[[obstacles]]\nappear_s = 5.0\nleave_s = 2.0\n",
     r"obstacles\[1\].leave_s = 2: must be after appear_s = 5"),
    ("[[obstacles]]\nhidden_from_s = 5.0\nhidden_until_s = 5.0\n",
     r"obstacles\[0\].hidden_until_s = 5: must be after hidden_from_s = 5"),
    ("[[obstacles]]\nhidden_until_s = 5.0\n", r"obstacles\[0\]: hidden_until_s and hidden_channels need hidden_from_s"),
    ("[[obstacles]]\nhidden_channels = [1]\n", r"obstacles\[0\]: hidden_until_s and hidden_channels need hidden_from_s"),
    ("[[obstacles]]\nhidden_from_s = 1.0\nhidden_channels = [0, 6]\n", r"obstacles\[0\].hidden_channels = 6: must be in \[0, 5\]"),
    ("[[obstacles]]\nhidden_from_s = 1.0\nhidden_channels = []\n", r"obstacles\[0\].hidden_channels: must be a non-empty list"),
    ("[[obstacles]]\nhidden_from_s = 1.0\nhidden_channels = [2, 2]\n", r"obstacles\[0\].hidden_channels: names a channel twice"),
    ("[[faults]]\nkind = 'silence'\nchannel = 1\nstart_s = 5.0\nend_s = 2.0\n", "end_s = 2 must be after start_s"),
    ("[[faults]]\nkind = 'silence'\nstart_s = 5.0\n", "needs a channel"),
    ("[[faults]]\nkind = 'blind'\nchannel = 2\nstart_s = 5.0\n", "every channel"),
    ("[[faults]]\nkind = 'silence'\nchannel = 1\nstart_s = 1.0\nrate = 5\n", "only a babble fault has a rate"),
    ("[monitor]\ntopology = '1oo2'\n", "topology"),
    ("[monitor]\ntimeout_cycles = 0\n", "monitor"),
    ("[braking]\nemergency_decel = 2.0\n", "missing key"),
    ("[campaign]\nfault_start_s = [5.0, 1.0]\n", "campaign.fault_start_s"),
])
def test_values_out_of_range_are_refused(tmp_path, text, match):
    refused(write(tmp_path, text), match)


def test_malformed_toml_names_the_file_and_the_line(tmp_path):
    path = write(tmp_path, 'description = "x"\n[train]\nspeed_mps = = 3\n')
    message = refused(path, "malformed TOML")
    assert "line 3" in message


def test_unknown_name_lists_the_catalogue():
    with pytest.raises(sc.ScenarioError, match="no such scenario") as exc:
        sc.load("no-such-thing")
    assert "static-obstacle" in str(exc.value)


def test_a_file_of_ones_own_and_its_defaults(tmp_path):
    s = sc.load(write(tmp_path, "[train]\nspeed_mps = 20\nemergency_decel_mps2 = [[0, 2.4], [30, 2.2]]\n"
                                "[[obstacles]]\nposition_m = 500\n", "my-world.toml"))
    assert s.name == "my-world" and s.train.speed_mps == 20.0 and s.duration_s == 60.0
    assert s.train.emergency_decel_mps2 == ((0.0, 2.4), (30.0, 2.2))
    assert s.train.emergency_at(10.0) == 2.4 and s.train.emergency_at(31.0) == 2.2
    assert s.obstacles == (sc.ObstacleSpec(500.0),) and s.sensors == sc.SensorSpec() and s.table is None
    assert sc.players(s) == ("run", "cosim")            # no [campaign] table: not one of the campaign's worlds


def test_an_obstacle_leaves_the_track_at_leave_s(tmp_path):
    """leave_s (issue 29 item 4): the obstacle is on the track from appear_s until leave_s;
    absent, it never leaves. run and cosim play it (cosim as the train FMU's
    obstacle.leave_time), the campaign refuses it in one line; a Scenario built in code is
    checked the same way as a file."""
    from dataclasses import replace

    from fmu import scenario as cosim_scenarios

    assert sc.ObstacleSpec().leave_s == sc.FOREVER_S
    s = sc.load(write(tmp_path, "[[obstacles]]\nposition_m = 400\nappear_s = 1.0\nleave_s = 3.5\n"))
    (o,) = s.obstacles
    assert (o.appear_s, o.leave_s) == (1.0, 3.5)
    assert [o.there(t) for t in (0.9, 1.0, 3.4, 3.5, 100.0)] == [False, True, True, False, False]
    assert sc.ObstacleSpec().there(1e6)
    assert sc.players(s) == ("run",)                    # appear_s = 1: not cosim; no [campaign]: not the campaign
    now = sc.load(write(tmp_path, "[[obstacles]]\nposition_m = 400\nleave_s = 3.5\n[campaign]\n", "now.toml"))
    assert sc.players(now) == ("run", "cosim")
    assert sc.refusal(now, "campaign") == \
        "obstacles[0].leave_s: the campaign's obstacles stay on the track; it plays no leave_s"
    assert cosim_scenarios.adapt(now).train["obstacle.leave_time"] == 3.5
    assert cosim_scenarios.adapt(sc.load("static-700m-30")).train["obstacle.leave_time"] == sc.FOREVER_S
    sc.check(now)
    with pytest.raises(sc.ScenarioError, match=r"obstacles\[0\].leave_s = 0: must be after appear_s = 0") as exc:
        sc.check(replace(now, obstacles=(replace(o, appear_s=0.0, leave_s=0.0),)))
    assert "\n" not in str(exc.value)


def test_a_hidden_obstacle_is_on_the_track_but_not_seen_by_the_channels_it_hides_from(tmp_path):
    """hidden_from_s, hidden_until_s, hidden_channels (issue 38 item 2): the channels it hides
    from see past it, to the next obstacle; the others and the train's collision still see it.
    run plays it (the player's sensors report the nearest obstacle each channel sees), cosim
    and the campaign refuse it in one line."""
    from can_bus.player import Player

    s = sc.load(write(tmp_path, "[[obstacles]]\nposition_m = 400\nhidden_from_s = 1.0\nhidden_until_s = 3.0\n"
                                "hidden_channels = [0, 1]\n[[obstacles]]\nposition_m = 900\n[sensors]\nrange_m = 2000\n"
                                "noise_sigma_m = 0\n"))
    a, b = s.obstacles
    assert (a.hidden_from_s, a.hidden_until_s, a.hidden_channels) == (1.0, 3.0, (0, 1))
    assert [a.seen_by(t, 0) for t in (0.9, 1.0, 2.9, 3.0)] == [True, False, False, True]
    assert all(a.seen_by(t, 2) and a.there(t) for t in (0.9, 1.0, 2.9, 3.0))
    assert b.hidden_channels == (0, 1, 2, 3, 4, 5) and b.seen_by(1.5, 0)
    assert sc.players(s) == ("run",)
    one = sc.load(write(tmp_path, "[[obstacles]]\nposition_m = 400\nhidden_from_s = 1.0\n[campaign]\n", "one.toml"))
    assert sc.refusal(one, "cosim").startswith("obstacles[0].hidden_from_s: the train FMU's sensors always see")
    assert sc.refusal(one, "campaign").startswith("obstacles[0].hidden_from_s: the campaign's faults hide")
    player = Player.__new__(Player)
    player.scenario, player.position, player.t = s, 0.0, 2.0
    assert player.obstacle_distance(0)[0] == 900.0 and player.obstacle_distance(2)[0] == 400.0
    assert player.obstacle_distance()[0] == 400.0                    # what the train runs into
    sc.check(s)


def test_monitor_and_braking_become_one_configuration(tmp_path):
    from monitor.core.config import Config
    from monitor.declaration import shipped

    decl = "\n".join(f"{k} = {v!r}" for k, v in {**shipped(), "emergency_decel": 2.0}.items())
    s = sc.load(write(tmp_path, f"[monitor]\nemergency_release = 0\ntopology = 2\n[braking]\n{decl}\n"))
    cfg = sc.monitor_config(s)
    assert cfg.emergency_decel_mms2 == 2000 and cfg.emergency_release == 0 and cfg.topology == "2oo2"
    assert cfg._replace(emergency_decel_mms2=2400, emergency_band2_cms=3000, emergency_band2_mms2=2200,
                        emergency_release=1, topology="3oo3") == Config()
    refused(write(tmp_path, f"[monitor]\nservice_decel_mms2 = 700\n[braking]\n{decl}\n"), "set by both")


# ----------------------------------------------------------------------------- the catalogue

@pytest.mark.parametrize("name", NAMES)
def test_every_catalogue_file_loads_and_its_players_accept_it(name):
    from can_bus import scenario as run_scenarios
    from fmu import scenario as cosim_scenarios

    entry = dict((e.name, e) for e in CATALOGUE)[name]
    s = sc.load(name)
    assert s.name == name and s.description and entry.description == s.description
    assert entry.players, f"{name}: no player can play it"
    for player in sc.PLAYERS:
        if player in entry.players:
            sc.require(s, player)
        else:
            with pytest.raises(sc.ScenarioError, match=re.escape(f"{name}.toml: ")):
                sc.require(s, player)
    if "run" in entry.players:
        assert run_scenarios.load(name) == s
    if "cosim" in entry.players:
        c = cosim_scenarios.load(name)
        assert c.name == name and c.duration_s == s.duration_s and c.table == (s.table or DEFAULT_TABLE)
    if "campaign" in entry.players:
        import verification.campaign as cp

        assert name in cp.SCENARIO_NAMES + (cp.GHOST_NAME,)


def test_the_campaign_plays_its_worlds_from_the_catalogue():
    import verification.campaign as cp

    assert [s.name for s in cp.SCENARIOS] == list(cp.SCENARIO_NAMES)
    assert all("campaign" in dict((e.name, e.players) for e in CATALOGUE)[n] for n in cp.SCENARIO_NAMES + (cp.GHOST_NAME,))
    assert cp.SCENARIO_BY_NAME["no-obstacle"].campaign.fault_start_s == (0.5, 18.0)
    assert cp.SCENARIO_BY_NAME["sudden-120m"].obstacles == (sc.ObstacleSpec(270.0, 5.0, 0.0, "static"),)


def test_one_name_one_world():
    """Names are file names, so unique; and no two files hold the same world under two names
    (the player's and the FMU's catalogues merged: where they differed, the names differ)."""
    assert len(NAMES) == len(set(NAMES))
    worlds = {}
    for name in NAMES:
        s = sc.load(name)
        world = (s.train, s.obstacles, s.sensors, s.faults, s.duration_s, tuple(sorted(s.monitor.items())),
                 repr(sorted((s.braking or {}).items())))
        assert world not in worlds, f"{name} and {worlds.get(world)} are the same world"
        worlds[world] = name
    # the names both old catalogues had: one world each, played by both
    for name in ("static-obstacle", "moving-obstacle", "no-obstacle"):
        assert {"run", "cosim"} <= set(dict((e.name, e.players) for e in CATALOGUE)[name])


def test_the_shells_list_what_they_play():
    from can_bus import scenario as run_scenarios
    from fmu import scenario as cosim_scenarios

    assert run_scenarios.shipped_names() == [e.name for e in CATALOGUE if "run" in e.players]
    assert cosim_scenarios.shipped() == [e.name for e in CATALOGUE if "cosim" in e.players]
    assert "fault-cascade" in run_scenarios.shipped_names() and "fault-cascade" not in cosim_scenarios.shipped()


# ----------------------------------------------------------------------------- the players' refusals

def test_cosim_refuses_what_the_train_fmu_cannot_play(tmp_path):
    from fmu import scenario as cosim_scenarios

    with pytest.raises(cosim_scenarios.CosimScenarioError) as exc:
        cosim_scenarios.load("fault-cascade")
    assert str(exc.value) == ("fault-cascade.toml: faults[1]: the train FMU injects one fault; cosim plays scenarios "
                              "with at most one")
    assert isinstance(exc.value, sc.ScenarioError) and isinstance(exc.value, ValueError)
    two = write(tmp_path, "[[obstacles]]\nposition_m = 500\n[[obstacles]]\nposition_m = 900\n")
    with pytest.raises(cosim_scenarios.CosimScenarioError, match=re.escape(f"{two}: obstacles[1]: the train FMU has one")):
        cosim_scenarios.load(two)
    late = write(tmp_path, "[[obstacles]]\nposition_m = 500\nappear_s = 3.0\n", "late.toml")
    with pytest.raises(cosim_scenarios.CosimScenarioError, match=r"obstacles\[0\].appear_s"):
        cosim_scenarios.load(late)
    crc = write(tmp_path, "[[faults]]\nkind = 'bad_crc'\nchannel = 0\nstart_s = 1.0\n", "crc.toml")
    with pytest.raises(cosim_scenarios.CosimScenarioError, match=r"faults\[0\].kind = 'bad_crc'"):
        cosim_scenarios.load(crc)


def test_the_player_refuses_what_it_cannot_play(tmp_path):
    from can_bus import scenario as run_scenarios

    with pytest.raises(run_scenarios.ScenarioError) as exc:
        run_scenarios.load("stress-blackout-release")
    assert str(exc.value).startswith("stress-blackout-release.toml: train.brake_delay_s: ") and "\n" not in str(exc.value)
    assert isinstance(exc.value, sc.ScenarioError)
    for text, key in (("[train]\ngradient_permille = 10\n", "train.gradient_permille"),
                      ("[train]\nmax_traction_mps2 = 0.5\n", "train.max_traction_mps2"),
                      ("[[faults]]\nkind = 'nan_distance'\nchannel = 1\nstart_s = 1.0\n", r"faults\[0\].kind"),
                      ("[monitor]\nemergency_release = 0\n", "monitor: `railguard run` configures"),
                      ("demand_delay_cycles = 0\n", "demand_delay_cycles")):
        with pytest.raises(run_scenarios.ScenarioError, match=key):
            run_scenarios.load(write(tmp_path, text))
    # values a player cannot play but written at their defaults are played
    assert run_scenarios.load(write(tmp_path, "[train]\ngradient_permille = 0.0\nbrake_delay_s = 0\n")).train == sc.TrainSpec()


def test_the_campaign_refuses_worlds_it_does_not_draw(tmp_path):
    for text, key in (("[campaign]\n[train]\nbrake_delay_s = 0.2\n", "train.brake_delay_s: the campaign draws"),
                      ("[campaign]\n[sensors]\nrange_m = 400.0\n", "sensors: the campaign's sensors"),
                      ("[campaign]\n[[faults]]\nkind = 'silence'\nchannel = 1\nstart_s = 1.0\n", "injects its own"),
                      ("[train]\nspeed_mps = 20.0\n", r"campaign: no \[campaign\] table")):
        with pytest.raises(sc.ScenarioError, match=key):
            sc.require(sc.load(write(tmp_path, text)), "campaign")


def test_the_stress_failure_is_written_in_the_one_language(tmp_path):
    """write_cosim_scenario on the declaration's worst corner and a lone blindness gives the
    shipped stress-blackout-release world; cosim plays it, the player refuses it in one line."""
    from can_bus import scenario as run_scenarios
    from fmu import scenario as cosim_scenarios
    from monitor.core.config import Config
    from verification import stress as st
    from verification import world_train

    cfg = Config()
    d = st.Disturbance.none()
    d.blind[22:34] = True
    path = st.write_cosim_scenario("m2", st.ENCOUNTERS["edge-30"], d, world_train.corners(cfg)[0], cfg,
                                   tmp_path / "failure.cosim.toml")
    written, shipped = sc.load(str(path)), sc.load("stress-blackout-release")
    assert (written.train, written.obstacles, written.sensors, written.faults, written.table) == \
        (shipped.train, shipped.obstacles, shipped.sensors, shipped.faults, shipped.table)
    assert cosim_scenarios.load(str(path)).train == cosim_scenarios.load("stress-blackout-release").train
    with pytest.raises(run_scenarios.ScenarioError, match="brake_delay_s"):
        run_scenarios.load(str(path))


def test_world_train_tables_take_the_scenario_names():
    from verification import world_train as wt

    a = wt.from_mapping({"brake_delay_s": 1.5, "brake_buildup_s": 0.0, "emergency_decel_mps2": 1.0,
                         "service_decel_mps2": 0.5, "gradient_permille": -10.0}, "w")
    b = wt.from_mapping({"brake_delay": 1.5, "brake_buildup": 0.0, "emergency_decel": 1.0, "service_decel": 0.5,
                         "gradient": -10.0}, "w")
    assert a == b
    with pytest.raises(wt.WorldTrainError, match="same value"):
        wt.from_mapping({"brake_delay_s": 1.5, "brake_delay": 1.5}, "w")


# ----------------------------------------------------------------------------- the documentation

def test_docs_list_every_shipped_scenario_and_every_key():
    doc = (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8")
    table = doc[doc.index("## The catalogue"):]
    rows = dict(re.findall(r"^\| `([a-z0-9-]+)` \| ([^|]*) \|", table[:table.index("\n\n", table.index("|---"))], flags=re.M))
    assert sorted(rows) == NAMES, "docs/scenarios.md's catalogue table is not the shipped catalogue"
    for e in CATALOGUE:
        assert rows[e.name].strip() == ", ".join(e.players), f"{e.name}: players in docs/scenarios.md"
    from dataclasses import fields

    for cls in (sc.TrainSpec, sc.ObstacleSpec, sc.SensorSpec, sc.FaultSpec, sc.CampaignSpec):
        for f in fields(cls):
            assert f"`{f.name}`" in doc, f"docs/scenarios.md does not document {cls.__name__}.{f.name}"
    for key in sc.TOP_KEYS:                              # keys, [tables] and [[arrays of tables]]
        assert re.search(rf"`\[{{0,2}}{key}\]{{0,2}}`", doc), f"docs/scenarios.md does not document {key}"
