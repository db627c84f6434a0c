"""Planning and replay against their cost (issue 23, item 4; docs/planning.md).

Usage: python scripts/studies/planning_summary.py DIR ... [--experiments N] [--plot FILE.png]
    [--curves FILE.png]

Each DIR is an `rmac-mj sweep --out` directory (docs/studies/planning.toml, planning-to-100.toml,
planning-200.toml, planning-mlac*.toml, fastest.toml) or a run directory of `reproduce` with
`--evaluate-every`; unfinished runs are left out (named on stderr). Prints one markdown row per learner and run, named
by the learner's config overrides (planning or replay steps first), with ``--experiments N`` over
only the first N experiments of each: the mean greedy return after trials 20 and 100 with 95%
intervals; the first trial at which the mean greedy return reaches the level within 20% and within
10% of the near-optimal return (-898 and -823 on the swing-up); the exploring return of the last 10
trials against the exploration floor (the near-optimal policy with the protocol's exploration);
the stuck experiments (the last five greedy trials worse than twice the optimum); and the CPU
seconds per simulated minute (the experiment's process, greedy trials included). ``--plot``
draws the trade-off: simulated minutes until the mean greedy return reaches each level against CPU
seconds per simulated minute, every learner and setting a point; ``--curves`` the mean greedy
curves.
"""

import argparse
import json
import pathlib
import sys

import numpy as np

from rmac_mj.agents import display_name
from rmac_mj.evaluation import (
    GREEDY_WITHIN,
    confidence_interval,
    first_reaching,
    stuck_threshold,
    within_optimal,
)
from rmac_mj.results import ResultStore
from rmac_mj.sweeps import flatten

#: Trials after which the greedy return is tabulated (issue 23: one simulated minute, five).
AT_TRIALS = (20, 100)
#: Trials at the end of a run whose exploring returns are held against the exploration floor.
LAST = 10
#: An experiment is stuck when the mean of its last this many greedy trials is worse than twice
#: the near-optimal return (``metrics.stuck_threshold``: -1496 on the swing-up): its policy does not
#: swing up. (``summary.json``'s count judges the mean exploring return of the last 50 trials, half
#: of a 100-trial run, which counts an experiment that learned at trial 60 as stuck.)
STUCK_EVALUATIONS = 5


def runs(paths):
    """The run directories under the given paths (a sweep's configurations, or a run itself)."""
    for path in map(pathlib.Path, paths):
        index = path / "sweep.json"
        if index.exists():
            for configuration in json.loads(index.read_text())["configurations"]:
                yield path / configuration["directory"]
        else:
            yield path


def setting(overrides: dict) -> tuple[str, int, str]:
    """(kind, steps, label) of a learner's config overrides: kind 'planning', 'replay' or ''."""
    kind = next((k for k in ("planning", "replay") if overrides.get(k, {}).get("steps")), "")
    steps = overrides[kind]["steps"] if kind else 0
    rest = {k: v for k, v in flatten(overrides).items() if k != f"{kind}.steps"}
    label = " ".join([f"{kind} {steps}"] if kind else []) or "none"
    if rest:
        label += ", " + ", ".join(f"{k} {v}" for k, v in rest.items())
    return kind, steps, label


def rows(paths, experiments: int | None = None):
    """One dict of metrics per (run, learner); ``experiments``: only the first that many."""
    for directory in runs(paths):
        store = ResultStore(directory)
        protocol = store.read_protocol()
        if not store.summary_path.is_file():
            print(f"# {directory}: not finished, left out", file=sys.stderr)
            continue
        summary = store.read_summary()
        optimal = summary.get("optimal_return")
        for learner in protocol["algorithms"]:
            n = (
                protocol["experiments"]
                if experiments is None
                else min(experiments, protocol["experiments"])
            )
            curves = store.load_curves(learner, n)
            greedy, trials = curves.greedy_returns, curves.greedy_trials
            kind, steps, label = setting(protocol["agent_configs"].get(learner, {}))
            row = {
                "learner": learner,
                "run": directory.name,
                "kind": kind,
                "steps": steps,
                "setting": label,
                "experiments": n,
                "seed": protocol["seed"],
                "greedy_trials": trials,
                "greedy_mean": greedy.mean(axis=0),
                "trial_seconds": summary["trial_seconds"],
                "cpu_per_minute": float(
                    np.mean(curves.cpu_times)
                    / (curves.returns.shape[1] * summary["trial_seconds"] / 60)
                ),
                "stuck": None
                if optimal is None
                else int(
                    np.sum(greedy[:, -STUCK_EVALUATIONS:].mean(axis=1) < stuck_threshold(optimal))
                ),
                "floor": summary.get("exploration_floor"),
                "exploring": curves.returns[:, -LAST:].mean(axis=1),
            }
            for t in AT_TRIALS:
                if t in trials:
                    row[f"greedy_{t}"] = confidence_interval(greedy[:, list(trials).index(t)])
            if optimal is not None:
                for fraction in GREEDY_WITHIN:
                    row[f"within_{fraction}"] = first_reaching(
                        row["greedy_mean"], trials, within_optimal(optimal, fraction)
                    )
                row["levels"] = {f: within_optimal(optimal, f) for f in GREEDY_WITHIN}
            yield row


def _interval(ci) -> str:
    return "" if ci is None else f"{ci[0]:.0f} [{ci[1]:.0f}, {ci[2]:.0f}]"


def table(all_rows) -> str:
    levels = next((r["levels"] for r in all_rows if "levels" in r), {})
    heads = [
        f"first trial >= {levels[f]:.0f}" if f in levels else f"within {f:.0%}"
        for f in GREEDY_WITHIN
    ]
    lines = [
        "| learner | setting | experiments (seed) | greedy, trial 20 | greedy, trial 100 | "
        + " | ".join(heads)
        + f" | exploring, last {LAST} trials (floor) | stuck | CPU s / sim. min |",
        "|---" * (8 + len(heads)) + "|",
    ]
    for r in all_rows:
        reach = [str(r.get(f"within_{f}") or "not in run") for f in GREEDY_WITHIN]
        mean, low, high = confidence_interval(r["exploring"])
        floor = "" if r["floor"] is None else f" ({r['floor']:.0f})"
        stuck = "" if r["stuck"] is None else f"{r['stuck']}/{r['experiments']}"
        lines.append(
            f"| {display_name(r['learner'])} | {r['setting']} | "
            f"{r['experiments']} ({r['seed']}) | "
            f"{_interval(r.get('greedy_20'))} | {_interval(r.get('greedy_100'))} | "
            + " | ".join(reach)
            + f" | {mean:.0f} [{low:.0f}, {high:.0f}]{floor} | {stuck} | "
            f"{r['cpu_per_minute']:.1f} |"
        )
    return "\n".join(lines)


_COLOURS = {"rmac": "tab:blue", "s-ac": "tab:orange", "mlac": "tab:green"}
_MARKERS = {"": "o", "none": "o", "planning": "s", "replay": "^"}


def plot_tradeoff(all_rows, path: pathlib.Path) -> None:
    """Simulated minutes to each greedy level against CPU s per simulated minute."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import matplotlib.ticker

    levels = next(r["levels"] for r in all_rows if "levels" in r)
    fig, axes = plt.subplots(1, len(GREEDY_WITHIN), figsize=(11, 4.2), sharey=True)
    for ax, fraction in zip(np.atleast_1d(axes), GREEDY_WITHIN):
        never = max(r["greedy_trials"][-1] * r["trial_seconds"] / 60 for r in all_rows) * 1.08
        for r in all_rows:
            trial = r.get(f"within_{fraction}")
            minutes = never if trial is None else trial * r["trial_seconds"] / 60
            ax.scatter(
                r["cpu_per_minute"],
                minutes,
                color=_COLOURS.get(r["learner"], "k"),
                marker=_MARKERS.get(r["kind"], "o"),
                s=40,
                zorder=3,
                facecolors="none" if trial is None else _COLOURS.get(r["learner"], "k"),
            )
            # the steps; a star when other settings differ too (fastest.toml's actor step size)
            label = str(r["steps"]) + ("*" if "," in r["setting"] else "")
            ax.annotate(
                label,
                (r["cpu_per_minute"], minutes),
                textcoords="offset points",
                xytext=(4, 3),
                fontsize=7,
            )
        ax.axhline(never, color="grey", linewidth=0.8, linestyle=":")
        ax.set_xscale("log")
        ax.xaxis.set_major_locator(matplotlib.ticker.FixedLocator([0.1, 0.2, 0.5, 1, 2, 5, 10, 20]))
        ax.xaxis.set_major_formatter(matplotlib.ticker.FormatStrFormatter("%g"))
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_xlabel("CPU seconds per simulated minute")
        ax.set_title(
            f"mean greedy return >= {levels[fraction]:.0f} (within {fraction:.0%} of the optimum)",
            fontsize=9,
        )
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].set_ylabel(
        "simulated minutes until reached\n(open marker: not within the run)"
    )
    handles = [
        plt.Line2D([], [], color=c, marker="o", linestyle="", label=display_name(k))
        for k, c in _COLOURS.items()
        if any(r["learner"] == k for r in all_rows)
    ]
    handles += [
        plt.Line2D([], [], color="k", marker=m, linestyle="", markerfacecolor="none", label=k)
        for k, m in (("none", "o"), ("planning", "s"), ("replay", "^"))
    ]
    fig.legend(handles=handles, fontsize=8, loc="lower center", ncol=len(handles))
    fig.suptitle(
        "Planning and replay steps per real step (numbers; * other settings too): "
        "learning speed against CPU",
        fontsize=10,
    )
    fig.tight_layout(rect=(0, 0.07, 1, 1))
    fig.savefig(path, dpi=120)


def plot_curves(all_rows, path: pathlib.Path) -> None:
    """Mean greedy return per learner, one line per setting."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    learners = list(dict.fromkeys(r["learner"] for r in all_rows))
    fig, axes = plt.subplots(1, len(learners), figsize=(4.2 * len(learners), 4), sharey=True)
    for ax, learner in zip(np.atleast_1d(axes), learners):
        for r in (r for r in all_rows if r["learner"] == learner):
            minutes = np.asarray(r["greedy_trials"]) * r["trial_seconds"] / 60
            style = "-" if r["kind"] == "planning" else "--" if r["kind"] == "replay" else "k-"
            ax.plot(minutes, r["greedy_mean"], style, linewidth=1, label=r["setting"])
        for level in next(r["levels"] for r in all_rows if "levels" in r).values():
            ax.axhline(level, color="grey", linewidth=0.8, linestyle=":")
        ax.set_title(display_name(learner))
        ax.set_xlabel("simulated time [min]")
        ax.set_ylim(-3000, -700)
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    np.atleast_1d(axes)[0].set_ylabel("greedy return (sum of rewards per trial)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="+", help="sweep or run directories")
    parser.add_argument("--plot", type=pathlib.Path, help="the trade-off figure")
    parser.add_argument("--curves", type=pathlib.Path, help="the mean greedy curves")
    parser.add_argument(
        "--experiments",
        type=int,
        help="only each run's first N experiments (to compare runs of different sizes "
        "on the same seeds)",
    )
    args = parser.parse_args()
    all_rows = list(rows(args.paths, args.experiments))
    print(table(all_rows))
    if args.plot:
        plot_tradeoff(all_rows, args.plot)
    if args.curves:
        plot_curves(all_rows, args.curves)


if __name__ == "__main__":
    main()
