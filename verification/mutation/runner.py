"""Running mutants, each in a fresh process.

A fork server per job slot (`_SERVER`, run with `python -c`) imports pytest, Hypothesis and
numpy once, never the project, and forks one child per mutant; the child serves the mutated
module through an import hook (or builds the FMUs from a copy of fmu/c with the mutated
rg_core.c) and runs the judging tests with `pytest -x`. `run_python` and `run_c` run the
baseline first, then every mutant, `jobs` at a time, with a per-mutant timeout.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Iterable, Optional

from .mutant import Mutant
from .targets import C_DIR, C_SEQUENCES, C_TESTS, JOBS, PY_TESTS, Progress, ROOT, tests_for


_SERVER = r"""
# A fork server: imports what every run needs (pytest, Hypothesis, numpy; never the project),
# then forks one fresh child per job. The child serves the mutated source for the mutated
# module through an import hook placed first on sys.meta_path and runs pytest.
import importlib, importlib.abc, importlib.util, json, os, signal, sys, time
import numpy, pytest, _pytest.python, _pytest.runner, hypothesis, hypothesis.strategies, hypothesis.stateful
from hypothesis import Phase, settings
settings.register_profile("mutation", derandomize=True, database=None, deadline=None, print_blob=False,
                          phases=[Phase.explicit, Phase.reuse, Phase.generate], report_multiple_bugs=False)
settings.load_profile("mutation")


class Mutated(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def __init__(self, job):
        self.job = job

    def find_spec(self, name, path=None, target=None):
        if name == self.job["module"]:
            return importlib.util.spec_from_file_location(name, self.job["path"], loader=self)
        return None

    def create_module(self, spec):
        return None

    def exec_module(self, module):
        exec(compile(self.job["source"], self.job["path"], "exec"), module.__dict__)


def child(job, out):
    result = {"status": "survived", "detail": ""}

    def finish():
        with open(out, "w") as f:
            json.dump(result, f)
        os._exit(0)

    log = os.open(job["log"], os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
    os.dup2(log, 1)
    os.dup2(log, 2)
    # the repository first on the path, as for `python -m pytest` run from it: test modules
    # import helpers from other test modules (`from tests.test_core_cycle import ...`)
    sys.path.insert(0, job["root"])
    if job.get("c_source"):
        # a C mutant: the FMUs the comparison test builds are built from a copy of fmu/c
        # whose rg_core.c is the mutant; one that does not compile is stillborn
        import shutil, subprocess, tempfile
        import fmu.build
        c_dir = os.path.join(tempfile.mkdtemp(prefix="rg-cmut-"), "c")
        shutil.copytree(job["c_dir"], c_dir)
        with open(os.path.join(c_dir, "core", "rg_core.c"), "w") as f:
            f.write(job["c_source"])
        flags = [f for f in fmu.build.CFLAGS if f != "-Werror"]     # a mutant may warn (a || b && c)
        cc = subprocess.run([fmu.build.compiler(), *flags, "-c", "-o", os.devnull,
                             os.path.join(c_dir, "core", "rg_core.c")], capture_output=True, text=True)
        if cc.returncode != 0:
            result.update(status="stillborn", detail=(cc.stderr.strip().splitlines() or ["?"])[0][:200])
            finish()
        fmu.build.C_DIR = type(fmu.build.C_DIR)(c_dir)
        # the FMUs are built without optimisation (3 builds per mutant); the -O2 build
        # above decided that the mutant compiles (warnings allowed: a mutant may warn)
        fmu.build.CFLAGS = [f for f in flags if f != "-O2"] + ["-O0"]
    if job["module"]:
        sys.meta_path.insert(0, Mutated(job))
        try:
            importlib.import_module(job["module"])
        except BaseException as exc:
            result.update(status="killed", detail="import fails: %s: %s" % (type(exc).__name__, str(exc)[:200]))
            finish()

    class Record:
        def pytest_collection_modifyitems(self, items):
            # C mutants: the comparison test at a reduced size (sequences per table and
            # the edge-hit minimum scaled together, the minimum halved: hypothesis draws its
            # shortest sequences first, so the first n reach the edges less than n/N of all
            # do); 0 keeps the test as it is
            n = job.get("c_sequences") or 0
            for item in items:
                mod = getattr(item, "module", None)
                if n and mod is not None and hasattr(mod, "SEQUENCES_PER_TABLE") and hasattr(mod, "MIN_HITS"):
                    mod.MIN_HITS = max(1, mod.MIN_HITS * n // mod.SEQUENCES_PER_TABLE // 2)
                    mod.SEQUENCES_PER_TABLE = n

        def pytest_runtest_logreport(self, report):
            if report.failed and not result["detail"]:
                result["detail"] = report.nodeid

        def pytest_collectreport(self, report):
            if report.failed and not result["detail"]:
                result["detail"] = "collection: " + report.nodeid

    code = int(pytest.main(["-x", "-q", "-p", "no:cacheprovider", "--rootdir", job["root"], *job["tests"]],
                           plugins=[Record()]))
    if code == 1 or (code == 2 and result["detail"]):
        result["status"] = "killed"
    elif code != 0:
        result.update(status="error", detail="pytest exit code %d %s" % (code, result["detail"]))
    finish()


for line in sys.stdin:
    job = json.loads(line)
    out = job["log"] + ".result"
    t0 = time.perf_counter()
    pid = os.fork()
    if pid == 0:
        try:
            os.setpgid(0, 0)
            child(job, out)
        finally:
            os._exit(3)
    status = None
    while time.perf_counter() - t0 < job["timeout"]:
        done, st = os.waitpid(pid, os.WNOHANG)
        if done:
            status = st
            break
        time.sleep(0.02)
    if status is None:
        for target in (-pid, pid):
            try:
                os.kill(target, signal.SIGKILL)
            except OSError:
                pass
        os.waitpid(pid, 0)
        res = {"status": "timeout", "detail": "no verdict after %.0f s (counts as killed)" % job["timeout"]}
    else:
        try:
            with open(out) as f:
                res = json.load(f)
            os.unlink(out)
        except (OSError, ValueError):
            res = {"status": "killed", "detail": "the test process died (wait status %d)" % status}
    try:
        os.killpg(pid, signal.SIGKILL)     # anything the tests left behind
    except OSError:
        pass
    if res["status"] != "error":
        try:
            os.unlink(job["log"])
        except OSError:
            pass
    res["seconds"] = time.perf_counter() - t0
    sys.stdout.write(json.dumps(res) + "\n")
    sys.stdout.flush()
"""


def _module_name(rel: str) -> str:
    return rel[:-3].replace("/", ".")


class Server:
    """One fork server subprocess (see _SERVER); `run` sends it one job and waits for its verdict."""

    def __init__(self, workdir: Path):
        # bytecode written: pytest's rewritten test modules are cached after the first child
        # (unchanged by any mutant; the mutant itself is compiled from its source by the import
        # hook, never cached): about a second less per mutant than rewriting them every time
        env = dict(os.environ, PYTHONHASHSEED="0")
        env.pop("PYTHONDONTWRITEBYTECODE", None)
        self.workdir = workdir
        self.proc = subprocess.Popen([sys.executable, "-c", _SERVER], cwd=workdir, env=env, text=True,
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
        self.count = 0

    def run(self, module: str, path: str, source: str, tests: Iterable[str], timeout: float,
            c_source: str = "") -> tuple[str, str, float]:
        self.count += 1
        log = str(self.workdir / f"job-{id(self)}-{self.count}.log")
        job = {"module": module, "path": path, "source": source, "root": str(ROOT), "log": log,
               "tests": [str(ROOT / t) for t in tests], "timeout": timeout, "c_source": c_source,
               "c_dir": str(C_DIR), "c_sequences": C_SEQUENCES if c_source else 0}
        self.proc.stdin.write(json.dumps(job) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError("the mutation fork server died")
        res = json.loads(line)
        detail = res["detail"] + (f" (log: {log})" if res["status"] == "error" else "")
        return res["status"], detail, res["seconds"]

    def close(self) -> None:
        try:
            self.proc.stdin.close()
            self.proc.wait(timeout=30)
        except (OSError, subprocess.TimeoutExpired):
            self.proc.kill()
            self.proc.wait()


def run_python(mutants: list[Mutant], tests: Iterable[str] = PY_TESTS, jobs: int = JOBS,
               timeout: Optional[float] = None, progress: Progress = lambda m: None, baseline: bool = True) -> dict:
    """Baseline first (every selected test must pass on the real core), then every mutant,
    `jobs` at a time, each in a fresh process forked from one of `jobs` servers."""
    return _run_all(mutants, tests, jobs, timeout, progress, c=False, baseline=baseline)


def run_c(mutants: list[Mutant], jobs: int = JOBS, timeout: Optional[float] = None,
          progress: Progress = lambda m: None, tests: Iterable[str] = C_TESTS, baseline: bool = True) -> dict:
    """The C mutants against the Python-vs-C comparison test alone (C_TESTS): each one's
    FMUs are built from a copy of fmu/c with the mutated rg_core.c."""
    return _run_all(mutants, tests, jobs, timeout, progress, c=True, baseline=baseline)


def _run_all(mutants: list[Mutant], tests: Iterable[str], jobs: int, timeout: Optional[float],
             progress: Progress, c: bool, baseline: bool = True) -> dict:
    """Without `baseline` the selected tests are not first run on the real core (CI runs
    them anyway) and the per-mutant timeout must be given."""
    import queue
    import threading

    tests = tuple(tests)
    with tempfile.TemporaryDirectory(prefix="rg-mutation-") as tmp:
        work = Path(tmp)
        servers = [Server(work) for _ in range(max(1, jobs))]
        try:
            base = 0.0
            if baseline:
                status, detail, base = servers[0].run("", "", "", tests, 1800,
                                                      c_source=(C_DIR / "core" / "rg_core.c").read_text() if c else "")
                if status != "survived":
                    raise RuntimeError(f"the selected tests fail on the real core ({status}: {detail})")
                progress(f"baseline: the {len(tests)} test files pass on the real core in {base:.1f} s")
            limit = timeout if timeout is not None else max(60.0, 5 * base)
            todo: queue.Queue = queue.Queue()
            for m in mutants:
                todo.put(m)
            done = [0]
            lock = threading.Lock()
            failure: list[BaseException] = []

            def worker(server: Server) -> None:
                while not failure:
                    try:
                        m = todo.get_nowait()
                    except queue.Empty:
                        return
                    try:
                        if c:
                            m.status, m.detail, m.seconds = server.run("", "", "", tests, limit, c_source=m.source)
                        else:
                            m.status, m.detail, m.seconds = server.run(_module_name(m.file), str(ROOT / m.file),
                                                                       m.source, tests_for(m.file, tests), limit)
                    except BaseException as exc:  # noqa: BLE001 - reported after the threads stop
                        failure.append(exc)
                        return
                    with lock:
                        done[0] += 1
                        progress(f"[{done[0]}/{len(mutants)}] {m.status:8s} {m.id}  ({m.seconds:.1f} s)")

            threads = [threading.Thread(target=worker, args=(s,)) for s in servers]
            for t in threads:
                t.start()
            for t in threads:
                t.join()
            if failure:
                raise failure[0]
        finally:
            for s in servers:
                s.close()
    return {"baseline_seconds": round(base, 2), "timeout_seconds": round(limit, 1)}
