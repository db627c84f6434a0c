"""Redraw the README's Fig. 2 (docs/fig2_learning_curves.png) with the current code.

    python scripts/readme_figures.py results/paper            # run the paper's protocol there, then draw
    python scripts/readme_figures.py results/paper --experiments 10    # a smaller run (say so in the README)
    python scripts/readme_figures.py results/paper --draw-only         # redraw from its summary.json

The run is ``rmac-mj reproduce --algorithms rmac,s-ac,mlac --evaluate-every 20`` (seed 0; 40
experiments unless told), resumed if the directory holds part of it, with the near-optimal return
and the exploration floor; the figure is drawn from its ``summary.json`` by the same function that
draws every run's Fig. 2, so the README shows what a run of this commit draws.
"""

from __future__ import annotations

import argparse
import pathlib
import subprocess
import sys

ROOT = pathlib.Path(__file__).resolve().parent.parent
FIGURE = ROOT / "docs" / "fig2_learning_curves.png"
PROTOCOL = ["--algorithms", "rmac,s-ac,mlac", "--evaluate-every", "20", "--seed", "0"]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", type=pathlib.Path, help="the run's result directory")
    parser.add_argument("--experiments", type=int, default=40, help="experiments per learner")
    parser.add_argument(
        "--jobs", type=int, default=None, help="worker processes (default: all cores)"
    )
    parser.add_argument(
        "--draw-only", action="store_true", help="redraw from the run's summary.json"
    )
    parser.add_argument("--figure", type=pathlib.Path, default=FIGURE, help="the PNG to write")
    args = parser.parse_args(argv)

    from rmac_mj.figures import learning_curves_figure, save_figure
    from rmac_mj.results import ResultStore

    store = ResultStore(args.out)
    if not args.draw_only:
        command = [
            sys.executable,
            "-m",
            "rmac_mj",
            "reproduce",
            *PROTOCOL,
            "--experiments",
            str(args.experiments),
            "--out",
            str(args.out),
        ]
        if args.jobs is not None:
            command += ["--jobs", str(args.jobs)]
        if store.read_config() is not None and not store.summary_path.exists():
            command.append("--resume")  # a run interrupted before: finish it
        print(" ".join(command[2:]), flush=True)
        if (
            store.summary_path.exists()
            and store.read_summary()["protocol"]["experiments"] == args.experiments
        ):
            print(f"{args.out} holds the finished run; drawing it")
        else:
            subprocess.run(command, check=True)
    summary = store.read_summary()
    paths = save_figure(
        learning_curves_figure(
            {args.out.name: summary},
            optimal_return=summary.get("optimal_return"),
            exploration_floor=summary.get("exploration_floor"),
        ),
        args.figure.with_suffix(""),
        formats=("png",),
    )
    print("figure:", ", ".join(map(str, paths)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
