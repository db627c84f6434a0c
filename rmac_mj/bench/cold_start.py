"""``rmac-mj bench --cold``: the first minute of a new user, measured from empty caches.

Each figure comes from a fresh Python process with an empty ``RMAC_MJ_CACHE_DIR`` (a temporary
folder, removed after), so that numba compiles every kernel it needs and nothing is loaded from a
cache: :func:`learner_compile` is one learner's compile, as the command line's warm-up does it (a
learner built, one learning and one greedy trial); :func:`quick_run` is the README's first command,
``rmac-mj reproduce --experiments 4``, whole. CPU seconds (user + sys of the child) are the figure
that a busy machine changes least; the wall time comes with the load average it was measured at.
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
import tempfile
import time
from typing import Any

#: The learners whose compile ``rmac-mj bench --cold`` measures, one fresh process each.
COLD_LEARNERS = ("rmac", "s-ac", "mlac", "recommended")

#: Kernels listed per learner in the report, the costliest first.
TOP_KERNELS = 8

# The child: imports first (not counted as compiling), then the warm-up of one learner, with the
# CPU seconds of each kernel's compilation (numba's compile events; a kernel's own share, without the
# kernels it calls, which numba compiles first and separately unless they are inlined).
_CHILD = """
import collections, json, sys, time
started = time.process_time()
from numba.core import event
from rmac_mj import _cache, tasks
from rmac_mj.agents import make_agent
from rmac_mj.rollout import action_space_of, run_trial, state_space_of
env = tasks.load(sys.argv[2], sys.argv[3])
imported = time.process_time()
own, stack = collections.defaultdict(lambda: [0, 0.0]), []

class Timer(event.Listener):
    def on_start(self, ev):
        f = ev.data["dispatcher"].py_func
        name = f.__module__ + "." + f.__qualname__
        if not name.startswith("rmac_mj."):
            name = "(numba's own overloads: np.empty, linalg, ...)"
        stack.append([name, time.process_time(), 0.0])

    def on_end(self, ev):
        name, start, inner = stack.pop()
        spent = time.process_time() - start
        own[name][0] += 1
        own[name][1] += spent - inner
        if stack:
            stack[-1][2] += spent

event.register("numba:compile", Timer())
wall = time.perf_counter()
agent = make_agent(sys.argv[1], state_space_of(env), action_space_of(env), seed=0)
run_trial(env, agent, learn=True)
run_trial(env, agent, learn=False)
print(json.dumps({
    "import_cpu_s": imported - started,
    "compile_cpu_s": time.process_time() - imported,
    "compile_wall_s": time.perf_counter() - wall,
    "kernels": _cache.kernel_stats()["compiled"],
    "per_kernel": sorted(
        ([k.removeprefix("rmac_mj."), n, s] for k, (n, s) in own.items()), key=lambda r: -r[2]
    ),
}))
"""


def _empty_cache_env(cache: str) -> dict[str, str]:
    env = dict(os.environ, RMAC_MJ_CACHE_DIR=cache)
    env.pop("NUMBA_CACHE_DIR", None)  # else numba would use (and fill) that one
    return env


def _children_cpu() -> float:
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def learner_compile(
    algorithm: str, domain: str | None = None, task: str | None = None
) -> dict[str, Any]:
    """One learner's kernels compiled from an empty cache, in a fresh process: the CPU and wall
    seconds of building it and running its first learning and greedy trial (``compile_*``; the
    trials themselves take milliseconds), the imports' CPU apart, how many kernel signatures numba
    compiled, and ``per_kernel``: [kernel, signatures, CPU seconds of its own], the costliest first.
    The task: ``domain``/``task``, by default the suite's default task."""
    from rmac_mj.tasks import DEFAULT_TASK

    domain, task = domain or DEFAULT_TASK[0], task or DEFAULT_TASK[1]
    with tempfile.TemporaryDirectory(prefix="rmac-mj-cold-") as cache:
        out = subprocess.run(
            [sys.executable, "-c", _CHILD, algorithm, domain, task],
            env=_empty_cache_env(cache),
            check=True,
            capture_output=True,
            text=True,
        ).stdout
    return {"algorithm": algorithm, **json.loads(out.strip().splitlines()[-1])}


def quick_run(experiments: int = 4, jobs: int | None = None) -> dict[str, Any]:
    """The README's first command (``rmac-mj reproduce --experiments 4``) from empty caches, in a
    fresh process: its wall seconds, its CPU seconds (user + sys, workers included) and the load
    average before and after."""
    with tempfile.TemporaryDirectory(prefix="rmac-mj-cold-") as cache:
        command = [
            sys.executable,
            "-m",
            "rmac_mj",
            "reproduce",
            "--experiments",
            str(experiments),
            "--no-progress",
            "--out",
            os.path.join(cache, "quick"),
        ]
        if jobs is not None:
            command += ["--jobs", str(jobs)]
        load_before = os.getloadavg()[0]
        cpu, wall = _children_cpu(), time.perf_counter()
        subprocess.run(command, env=_empty_cache_env(cache), check=True, capture_output=True)
        wall, cpu = time.perf_counter() - wall, _children_cpu() - cpu
    return {
        "experiments": experiments,
        "wall_s": wall,
        "cpu_s": cpu,
        "load_before": load_before,
        "load_after": os.getloadavg()[0],
    }


def run(
    learners: tuple[str, ...] = COLD_LEARNERS, quick: bool = True, **where: str
) -> dict[str, Any]:
    """Every learner's cold compile (:func:`learner_compile`), one after another, then the quick
    run (:func:`quick_run`) if ``quick``."""
    report: dict[str, Any] = {"cpus": os.cpu_count(), "load_before": os.getloadavg()[0]}
    report["learners"] = [learner_compile(a, **where) for a in learners]
    if quick:
        report["quick_run"] = quick_run()
    return report


def format_table(report: dict[str, Any]) -> str:
    """The report for people: a line per learner, then the quick run."""
    lines = [
        f"from empty caches, on {report['cpus']} CPUs at load {report['load_before']:.1f} "
        "(CPU = user + sys; the wall time depends on the load)",
        f"{'learner':>8} {'compile CPU':>12} {'compile wall':>13} {'kernels':>8} {'imports CPU':>12}",
    ]
    for row in report["learners"]:
        lines.append(
            f"{row['algorithm']:>8} {row['compile_cpu_s']:>10.1f} s {row['compile_wall_s']:>11.1f} s "
            f"{row['kernels']:>8d} {row['import_cpu_s']:>10.1f} s"
        )
        for name, signatures, seconds in row["per_kernel"][:TOP_KERNELS]:
            lines.append(f"{'':>8} {seconds:>10.1f} s  {name} ({signatures} signatures)")
    quick = report.get("quick_run")
    if quick is not None:
        lines.append(
            f"quick run (rmac-mj reproduce --experiments {quick['experiments']}): "
            f"{quick['wall_s']:.0f} s wall, {quick['cpu_s']:.0f} s CPU, load "
            f"{quick['load_before']:.1f} before and {quick['load_after']:.1f} after"
        )
    return "\n".join(lines)
