"""The figure of docs/studies/upright-offset.md.

Usage: python scripts/studies/upright_offset_figure.py PAPER_CSV REPEAT_TARGET_CSV REPEAT_RATE_CSV
           SNAPSHOT OUT.png

PAPER_CSV: ``scripts/upright_offset.py RESULT --csv`` of a run with all three learners; the REPEAT
CSVs: ``--repeat`` runs of RMAC (consecutive greedy trials one learning trial apart) with the paper's
reference insertion and with ``reference_insert_rate`` RATE (0.3); SNAPSHOT: one RMAC snapshot whose
reference model is drawn over consecutive learning trials under both insertions.
"""

import csv
import pathlib
import sys

import numpy as np

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1]))
import upright_offset as uo  # noqa: E402

from rmac_mj import rollout as episode
from rmac_mj import tasks  # noqa: E402

RATE = 0.3


def rows(path):
    with open(path) as handle:
        return list(csv.DictReader(handle))


def main(paper_csv, target_csv, rate_csv, snapshot, out):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (a, b, c) = plt.subplots(1, 3, figsize=(15, 4.2))
    # (a) where the greedy policies settle: every steady state is a holding equilibrium.
    names = {"rmac": "RMAC", "s-ac": "S-AC", "mlac": "MLAC"}
    for algorithm, label in names.items():
        group = [
            r
            for r in rows(paper_csv)
            if r["algorithm"] == algorithm
            and r["settle_step"]
            and abs(float(r["phi_ss"])) < uo.UPRIGHT
        ]
        a.plot(
            [float(r["phi_ss"]) for r in group],
            [float(r["u_ss"]) for r in group],
            "o",
            ms=4,
            alpha=0.7,
            label=f"{label} ({len(group)} experiments)",
        )
    phi = np.linspace(-0.25, 0.25, 101)
    a.plot(phi, -4.02 * np.sin(phi), "k--", lw=0.8, label="holding voltage -4.02 sin(phi)")
    a.set(
        xlabel="steady-state angle phi_ss (rad, 0 = upright)",
        ylabel="steady-state voltage (V)",
        title="(a) greedy trial after 600 trials",
    )
    a.legend(fontsize=7)
    # (b) the offset is redrawn by every learning trial.
    for data, colour, label in (
        (rows(target_csv), "C0", "paper (insert x_r)"),
        (rows(rate_csv), "C3", f"insert rate {RATE}, after 30 trials"),
    ):
        for index in range(8):
            series = sorted(
                (r for r in data if int(r["experiment"]) == index), key=lambda r: int(r["repeat"])
            )
            b.plot(
                [int(r["repeat"]) + 0.08 * index for r in series],
                [float(r["phi_ss"]) for r in series],
                "-o",
                color=colour,
                ms=3,
                lw=0.6,
                alpha=0.8,
                label=label if index == 0 else None,
            )
    b.axhline(0, color="k", lw=0.5)
    b.set(
        xlabel="learning trials after the snapshot (one greedy trial after each)",
        ylabel="steady-state angle phi_ss (rad)",
        ylim=(-0.3, 0.3),
        title="(b) phi_ss of 8 experiments, trial after trial",
    )
    b.legend(fontsize=7)
    # (c) the reference model's demanded speed at rest, R_phidot(phi, 0), over 5 learning trials.
    phis = np.linspace(-0.3, 0.3, 121)
    for insert, colour in (("target", "C0"), ("rate", "C3")):
        overrides = {} if insert == "target" else {"reference_insert_rate": RATE}
        agent, meta = uo.load_agent(pathlib.Path(snapshot), overrides, 0)
        env = tasks.load(meta["domain"], meta["task"], task_kwargs=meta["task_kwargs"])
        for _ in range(30 if insert == "rate" else 0):
            episode.run_trial(env, agent, learn=True)
        for t in range(5):
            c.plot(
                phis,
                [agent.reference.query([p, 0.0])[0][1] for p in phis],
                color=colour,
                lw=0.9,
                alpha=0.5 + 0.1 * t,
                label=(
                    "paper (insert x_r)"
                    if insert == "target"
                    else f"insert rate {RATE}, after 30 trials"
                )
                if t == 0
                else None,
            )
            episode.run_trial(env, agent, learn=True)
    c.axhline(0, color="k", lw=0.5)
    c.axvline(0, color="k", lw=0.5)
    c.set(
        xlabel="phi (rad), at phi_dot = 0",
        ylabel="desired next speed R(x) (rad/s)",
        title="(c) RMAC reference at rest, 5 consecutive trials",
    )
    c.legend(fontsize=7)
    for axis in (a, b, c):
        axis.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out, dpi=110)


if __name__ == "__main__":
    main(*sys.argv[1:])
