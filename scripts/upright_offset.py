"""Where learned greedy policies settle after the swing-up, and what the offset costs (study 5).

    python scripts/upright_offset.py RESULT_DIR [RESULT_DIR ...] [--trial 600] [--last 30]
        [--algorithms rmac s-ac] [--csv FILE] [--pair-with RESULT_DIR] [--plot FILE.png]
        [--set ALGO.FIELD=VALUE ...] [--continue N] [--repeat R]
        [--policy learned|critic-greedy|oracle-inverse]
    python scripts/upright_offset.py ROWS.csv [...] [--pair-with BASE.csv]   # redraw saved tables

A RESULT_DIR is an ``rmac-mj reproduce`` directory or a sweep directory (every configuration under it
is taken). For every experiment, the agent's snapshot at ``--trial`` (reproduce always saves the last
trial's) is reloaded and one greedy trial is run, exactly as the runner's greedy evaluation does: the
swing-up task starts from [pi, 0] without noise and the greedy policy neither explores nor learns, so
the trial is deterministic. Where the runner evaluated a greedy trial after that learning trial, its
stored return is checked against the replayed one (to 1e-9).

Per experiment (the state x_k is the one the action u_k is applied in):

* ``phi_ss``, ``phi_dot_ss``, ``u_ss``: the steady state, the means over the last ``--last`` steps;
  ``phi_std``: the spread of phi over them (a settled policy has ~0);
* ``settle_step``: the first step from which |phi - phi_ss| < 0.05 rad and |phi_dot| < 0.5 rad/s hold
  to the end of the trial (None when the policy never settles near its final angle);
* ``offset_loss``: the return lost to the offset, -sum of r_k from ``settle_step`` on: what the same
  trial would have scored had phi and u been 0 from there (r = -5 phi^2 - 0.1 phi_dot^2 - u^2 is 0
  there and every earlier reward is unchanged).

The summary gives per directory and learner, over the experiments whose greedy trial ends upright
(settled, |phi_ss| < 0.5 rad; stuck policies have no steady state to speak of), the mean of each
over experiments with its 95% CI,
how many settle on each side of upright, and (``--pair-with``) paired t-tests of |phi_ss| and of the
loss against another directory run with the same seeds (experiment i against experiment i).

Interventions, with the same learned memories (only RMAC's are wired here):

* ``--set FIELD=VALUE`` rebuilds the agent with that config field changed before loading its learned
  state (a JSON value; e.g. ``reference.neighbours=5``); fields that size the memories cannot change;
* ``--continue N`` first runs N more learning trials (exploring, with the overrides), continuing the
  experiment's own random stream from the snapshot, then the greedy trial;
* ``--policy critic-greedy`` replaces u = f^-1(x, R(x)) by the one-step lookahead on the learned
  process model and critic, u = argmax over 121 voltages of -P u^2 + gamma V(f(x, u)) (the process
  model linearised at the previous action, as the reachable rules do): it tells whether the critic
  alone puts the goal at upright;
* ``--policy oracle-inverse`` keeps the learned reference R but inverts the true dynamics (see
  :class:`OracleInverse`): it tells what the learned process model adds to the offset.
"""

from __future__ import annotations

import argparse
import csv
import json
import pathlib
import sys

import numpy as np
from scipy import stats

from rmac_mj import rollout as episode
from rmac_mj import tasks
from rmac_mj.agents import ActionSpace, StateSpace, make_agent
from rmac_mj.evaluation import confidence_interval
from rmac_mj.results import ResultStore, load_snapshot
from rmac_mj.results.snapshots import upgrade

SETTLE_ANGLE = 0.05  # rad, |phi - phi_ss| from the settle step on
SETTLE_SPEED = 0.5  # rad/s, |phi_dot| from the settle step on
UPRIGHT = 0.5  # rad: a trial "ends upright" when it settles (see settle_step) within this of 0
FIELDS = (
    "directory",
    "algorithm",
    "experiment",
    "repeat",
    "greedy_return",
    "stored_greedy_return",
    "phi_ss",
    "phi_dot_ss",
    "u_ss",
    "phi_std",
    "settle_step",
    "offset_loss",
    "critic_peak",
    "critic_switch",
    "critic_gain",
    "critic_points_back",
    "memory_near_upright",
    "critic_span_at_upright",
)
#: The slice phi_dot = 0 on which RMAC's learned memories are read (rad).
SLICE = np.linspace(-0.3, 0.3, 121)


def read_csv(path: pathlib.Path) -> list[dict]:
    """Rows written by ``--csv`` (so that a table can be redrawn without replaying the trials)."""
    rows = []
    with open(path, newline="") as handle:
        for row in csv.DictReader(handle):
            out: dict = {}
            for key, text in row.items():
                if key in ("directory", "algorithm"):
                    out[key] = text
                elif text == "":
                    out[key] = None
                elif key in (
                    "experiment",
                    "repeat",
                    "settle_step",
                    "memory_near_upright",
                    "critic_points_back",
                ):
                    out[key] = int(float(text))
                else:
                    out[key] = float(text)
            rows.append(out)
    return rows


def result_dirs(path: pathlib.Path) -> list[pathlib.Path]:
    """``path`` itself if it is a reproduce directory, else every one below it (a sweep)."""
    if (path / "config.json").is_file() and (path / "snapshots").is_dir():
        return [path]
    found = sorted(
        p.parent for p in path.glob("*/config.json") if (p.parent / "snapshots").is_dir()
    )
    if not found:
        raise SystemExit(
            f"upright_offset: {path} holds no reproduce result directory with snapshots"
        )
    return found


def greedy_trajectory(agent, env) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One greedy trial as ``episode.run_trial(learn=False)`` runs it; returns the states x_k (steps,
    n) in which the actions u_k (steps, m) were applied and the rewards r_k (steps,)."""
    keys = episode.learner_state_of(env).keys
    states, actions, rewards = [], [], []
    timestep = env.reset()
    x = episode.state_of(timestep.observation, keys)
    agent.begin_greedy_trial()
    while True:
        u = agent.greedy_action(x)
        states.append(x)
        actions.append(np.atleast_1d(u).astype(float))
        timestep = env.step(u)
        rewards.append(float(timestep.reward))
        x = episode.state_of(timestep.observation, keys)
        if timestep.last():
            return np.array(states), np.array(actions), np.array(rewards)


def steady_state(
    states: np.ndarray, actions: np.ndarray, rewards: np.ndarray, last: int
) -> dict[str, float | int | None]:
    """The steady-state metrics of one trial (see the module docstring)."""
    phi, phi_dot, u = states[:, 0], states[:, 1], actions[:, 0]
    phi_ss = float(phi[-last:].mean())
    near = (np.abs(phi - phi_ss) < SETTLE_ANGLE) & (np.abs(phi_dot) < SETTLE_SPEED)
    outside = np.flatnonzero(~near)
    settle = 0 if len(outside) == 0 else int(outside[-1]) + 1
    settle_step = settle if settle < len(phi) else None
    return {
        "phi_ss": phi_ss,
        "phi_dot_ss": float(phi_dot[-last:].mean()),
        "u_ss": float(u[-last:].mean()),
        "phi_std": float(phi[-last:].std()),
        "settle_step": settle_step,
        "offset_loss": (
            float(-rewards[settle_step:].sum()) if settle_step is not None else float("nan")
        ),
    }


def parse_sets(assignments: list[str]) -> dict:
    """``FIELD=VALUE`` pairs (dots for nested fields) as a nested dict of config overrides."""
    overrides: dict = {}
    for item in assignments:
        key, sep, text = item.partition("=")
        if not sep:
            raise SystemExit(f"upright_offset: --set {item!r}: expected FIELD=VALUE")
        try:
            value = json.loads(text)
        except json.JSONDecodeError:
            value = text
        *parents, leaf = key.split(".")
        node = overrides
        for name in parents:
            node = node.setdefault(name, {})
        node[leaf] = value
    return overrides


def _merge(config: dict, overrides: dict) -> dict:
    merged = dict(config)
    for key, value in overrides.items():
        merged[key] = _merge(merged.get(key, {}), value) if isinstance(value, dict) else value
    return merged


def load_agent(path: pathlib.Path, overrides: dict, index: int):
    """The snapshot's agent, rebuilt with ``overrides`` applied to its config (then its learned
    state loaded), and its meta document."""
    if not overrides:
        return load_snapshot(path)
    with np.load(path, allow_pickle=False) as data:
        meta = upgrade(json.loads(str(data["meta"])))  # an earlier format's names as today's
        state = {key[len("agent/") :]: data[key] for key in data.files if key.startswith("agent/")}
    agent = make_agent(
        meta["algorithm"],
        StateSpace(**meta["state_space"]),
        ActionSpace(**meta["action_space"]),
        config=_merge(meta["config"], overrides),
        seed=index,
    )
    agent.load_state_dict(state)
    return agent, meta


class CriticGreedy:
    """u = argmax_u -P |u|^2 + gamma V(f(x, u)) over ``n_actions`` voltages for a learned RMAC
    (see the module docstring); the greedy-trial interface of an Agent."""

    def __init__(self, agent, n_actions: int = 121):
        self.agent = agent
        self.candidates = np.linspace(
            agent.action_space.low[0], agent.action_space.high[0], n_actions
        )[:, None]
        self.u_prev = np.zeros(agent.m)

    def begin_greedy_trial(self) -> None:
        self.u_prev = np.zeros(self.agent.m)

    def greedy_action(self, x) -> np.ndarray:
        a = self.agent
        x = a._canonical(np.asarray(x, dtype=float))
        pred, beta, _ = a.process.query(np.concatenate([x, self.u_prev]))
        beta_u = beta[:, a.n : a.n + a.m]
        scores = [a._reachable_score(u, pred, beta_u, self.u_prev)[0] for u in self.candidates]
        self.u_prev = self.candidates[int(np.argmax(scores))].copy()
        return self.u_prev.copy()


class OracleInverse:
    """u = f^-1(x, R(x)) with the learned reference R but the *true* one-step dynamics in place of
    the learned process model: the voltage among 601 (0.01 V apart) whose simulated next state is
    nearest R(x) in the same unweighted least-squares sense as the learned inverse (a diagnostic for
    the dc_pendulum only: it reads the MuJoCo model)."""

    def __init__(self, agent, env, n_actions: int = 601):
        from rmac_mj.solvers.dynamic_programming_grid import simulate_transitions

        self.agent = agent
        self.model = env.physics.model.ptr
        self.n_sub = episode.n_sub_steps(env)
        self.candidates = np.linspace(
            agent.action_space.low[0], agent.action_space.high[0], n_actions
        )
        self.simulate = simulate_transitions

    def begin_greedy_trial(self) -> None:
        pass

    def greedy_action(self, x) -> np.ndarray:
        a = self.agent
        x = a._canonical(np.asarray(x, dtype=float))
        desired = a.reference.query(x)[0]
        n = len(self.candidates)
        nxt = self.simulate(
            self.model, np.full(n, x[0]), np.full(n, x[1]), self.candidates, self.n_sub
        )
        error = nxt - desired
        error[:, 0] = (error[:, 0] + np.pi) % (2 * np.pi) - np.pi
        return self.candidates[[int(np.argmin((error**2).sum(axis=1)))]]


def measure(
    directory: pathlib.Path,
    trial: int,
    last: int,
    algorithms: list[str] | None,
    overrides: dict | None = None,
    more_trials: int = 0,
    policy: str = "learned",
    repeats: int = 1,
) -> list[dict]:
    """One row per experiment and learner of a reproduce directory (``repeats`` rows each: a greedy
    trial, then one more learning trial before the next)."""
    overrides = overrides or {}
    rows = []
    protocol = json.loads((directory / "config.json").read_text())["protocol"]
    for algorithm in protocol["algorithms"]:
        if algorithms and algorithm not in algorithms:
            continue
        for exp_dir in sorted((directory / "snapshots" / algorithm).glob("exp_*")):
            index = int(exp_dir.name.split("_")[1])
            agent, meta = load_agent(
                exp_dir / f"trial_{trial:04d}.npz", overrides.get(algorithm, {}), index
            )
            env = tasks.load(meta["domain"], meta["task"], task_kwargs=meta["task_kwargs"])
            for _ in range(more_trials):
                episode.run_trial(env, agent, learn=True)
            for repeat in range(repeats):
                if repeat:
                    episode.run_trial(env, agent, learn=True)
                row = _measure_one(
                    directory,
                    algorithm,
                    index,
                    agent,
                    env,
                    trial,
                    last,
                    policy,
                    intervened=bool(overrides) or more_trials or repeat or policy != "learned",
                )
                rows.append({**row, "repeat": repeat})
    return rows


def _measure_one(
    directory: pathlib.Path,
    algorithm: str,
    index: int,
    agent,
    env,
    trial: int,
    last: int,
    policy: str,
    intervened: bool,
) -> dict:
    """The greedy trial of one agent as a row (see ``measure``)."""
    actor = {
        "learned": lambda: agent,
        "critic-greedy": lambda: CriticGreedy(agent),
        "oracle-inverse": lambda: OracleInverse(agent, env),
    }[policy]()
    states, actions, rewards = greedy_trajectory(actor, env)
    stored = None
    curve = directory / "curves" / algorithm / f"exp_{index:03d}.npz"
    if curve.is_file():
        with np.load(curve) as data:
            hit = np.flatnonzero(data["greedy_trials"] == trial)
            if len(hit):
                stored = float(data["greedy_returns"][hit[0]])
    if stored is not None and not intervened and abs(stored - rewards.sum()) > 1e-9:
        raise SystemExit(
            f"upright_offset: {directory} {algorithm} experiment {index}: the "
            f"replayed greedy return {rewards.sum()!r} differs from the stored "
            f"{stored!r}"
        )
    row = {
        "directory": str(directory),
        "algorithm": algorithm,
        "experiment": index,
        "greedy_return": float(rewards.sum()),
        "stored_greedy_return": stored,
        **steady_state(states, actions, rewards, last),
    }
    if algorithm == "rmac":
        row.update(rmac_memories(agent, row))
    return row


def rmac_memories(agent, row: dict) -> dict:
    """What RMAC's learned memories say around upright, on the slice phi_dot = 0 (SLICE):

    * ``critic_peak``: the angle of the critic's largest value V(phi, 0);
    * ``critic_switch``: where the vertex rule (Algorithm 2 line 16) switches from the +3 V vertex
      (below) to the -3 V one (above), nearest phi_ss: the zero of beta^C(phi, 0) . beta_u, the
      critic's local slope along the process model's input gain (at the steady state), falling;
    * ``critic_gain``: V(critic_peak, 0) - V(x_ss): what the critic thinks the offset costs;
    * ``critic_points_back``: 1 if at x_ss the vertex rule picks the vertex that pushes towards
      upright (the sign of the critic's slope along beta_u is that of -phi_ss), else 0;
    * ``critic_span_at_upright``: the range of phi (rad) that K([0, 0]), the critic's neighbours
      of the fit at upright, spans;
    * ``memory_near_upright``: critic samples with |phi| < 0.1 rad and |phi_dot| < 1 rad/s (the
      reference memory holds samples at the same inputs: both insert at x_{k-1}).
    """
    x_ss = np.array([row["phi_ss"], row["phi_dot_ss"]])
    _, beta, _ = agent.process.query(np.r_[x_ss, row["u_ss"]])
    beta_u = beta[:, agent.n]
    values, slopes = [], []
    for phi in SLICE:
        value, slope, _ = agent.critic.memory.query([phi, 0.0])
        values.append(value[0])
        slopes.append(slope[0, : agent.n] @ beta_u)
    values, slopes = np.array(values), np.array(slopes)
    falling = np.flatnonzero((slopes[:-1] > 0) & (slopes[1:] <= 0))
    switch = (
        float("nan")
        if len(falling) == 0
        else float(SLICE[falling][np.argmin(np.abs(SLICE[falling] - x_ss[0]))])
    )
    X = agent.critic.memory.X_[: agent.critic.memory.n_samples_]
    return {
        "critic_peak": float(SLICE[np.argmax(values)]),
        "critic_switch": switch,
        "critic_gain": float(values.max() - agent.critic.memory.query(x_ss)[0][0]),
        "critic_points_back": int(
            np.sign(agent.critic.memory.query(x_ss)[1][0, : agent.n] @ beta_u) == -np.sign(x_ss[0])
        ),
        "memory_near_upright": int(((np.abs(X[:, 0]) < 0.1) & (np.abs(X[:, 1]) < 1.0)).sum()),
        "critic_span_at_upright": float(
            np.ptp(X[agent.critic.memory.neighbours(np.zeros(agent.n)), 0])
        ),
    }


def upright(row: dict) -> bool:
    return row["settle_step"] is not None and abs(row["phi_ss"]) < UPRIGHT


def _ci(values) -> str:
    mean, low, high = confidence_interval(np.asarray(values, dtype=float))
    return f"{mean:.3f} [{low:.3f}, {high:.3f}]"


def summarise(rows: list[dict]) -> None:
    """One markdown row per directory and learner."""
    print(
        "| directory | learner | upright / exp. | phi_ss, mean [95% CI] (rad) | \\|phi_ss\\| | below / above 0 "
        "| u_ss (V) | \\|u_ss\\| | offset loss per trial | greedy return (all exp.) |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    groups: dict[tuple[str, str], list[dict]] = {}
    for row in rows:
        groups.setdefault((row["directory"], row["algorithm"]), []).append(row)
    for (directory, algorithm), every in groups.items():
        group = [r for r in every if upright(r)]
        phi = np.array([r["phi_ss"] for r in group])
        u = np.array([r["u_ss"] for r in group])
        loss = np.array([r["offset_loss"] for r in group])
        settled = np.isfinite(loss)
        print(
            f"| {pathlib.Path(directory).name} | {algorithm} | {len(group)}/{len(every)} | {_ci(phi)} "
            f"| {_ci(np.abs(phi))} | {(phi < 0).sum()} / {(phi > 0).sum()} | {_ci(u)} "
            f"| {_ci(np.abs(u))} | {_ci(loss[settled])} "
            f"| {_ci([r['greedy_return'] for r in every])} |"
        )
        if algorithm == "rmac" and len(group) > 2 and group[0].get("critic_switch", "") != "":
            switch = np.array(
                [np.nan if r["critic_switch"] is None else r["critic_switch"] for r in group],
                dtype=float,
            )
            peak = np.array([r["critic_peak"] for r in group])
            ok = np.isfinite(switch)
            print(
                f"|   | RMAC's critic: vertex-rule switch at {_ci(switch[ok])} rad, \\|switch\\| "
                f"{_ci(np.abs(switch[ok]))}, corr(phi_ss, switch) = "
                f"{np.corrcoef(phi[ok], switch[ok])[0, 1]:.2f} ({ok.sum()} exp.); peak of V(phi, 0) "
                f"\\|peak\\| {_ci(np.abs(peak))}, corr(phi_ss, peak) = "
                f"{np.corrcoef(phi, peak)[0, 1]:.2f}; V(peak) - V(x_ss) "
                f"{_ci([r['critic_gain'] for r in group])}; at x_ss the vertex rule pushes "
                f"back towards upright in {sum(r['critic_points_back'] for r in group)}/"
                f"{len(group)}; critic samples near upright "
                f"{_ci([r['memory_near_upright'] for r in group])} of "
                f"{agent_capacity(group)}; the critic's neighbours at upright span "
                f"{_ci([r['critic_span_at_upright'] for r in group])} rad of phi |||||||||"
            )
        if len(group) > 2 and np.ptp(phi) > 0:
            # Holding phi takes u = -c sin(phi) (gravity against the motor): fit c across experiments.
            s = np.sin(phi)
            c = -float(s @ u / (s @ s))
            sign = stats.binomtest(int((phi > 0).sum()), len(phi)).pvalue
            print(
                f"|   | fit u_ss = -c sin(phi_ss): c = {c:.2f} V/rad, residual rms "
                f"{np.sqrt(np.mean((u + c * s) ** 2)):.3f} V; sign test (as many above as below 0) "
                f"p = {sign:.2g} |||||||||"
            )


def persistence(rows: list[dict]) -> None:
    """Is an experiment's offset its own (persistent) or redrawn by every learning trial? Compares
    the spread of phi_ss within an experiment, over its consecutive greedy trials, with the spread
    between experiments, and correlates phi_ss one learning trial apart."""
    groups: dict[tuple[str, str], dict[int, list[dict]]] = {}
    for row in rows:
        groups.setdefault((row["directory"], row["algorithm"]), {}).setdefault(
            row["experiment"], []
        ).append(row)
    print(
        "\n| directory | learner | exp. x greedy trials (upright) | mean \\|phi_ss\\| | SD within an "
        "experiment | SD of the experiments' means | corr(phi_ss, next phi_ss) | sign kept to next "
        "trial |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for (directory, algorithm), by_exp in groups.items():
        series = [
            [r["phi_ss"] if upright(r) else np.nan for r in sorted(rs, key=lambda r: r["repeat"])]
            for rs in by_exp.values()
        ]
        phi = np.array(series)
        within = np.sqrt(np.nanmean(np.nanvar(phi, axis=1, ddof=1)))
        between = np.nanstd(np.nanmean(phi, axis=1), ddof=1)
        a, b = phi[:, :-1].ravel(), phi[:, 1:].ravel()
        ok = np.isfinite(a) & np.isfinite(b)
        corr = np.corrcoef(a[ok], b[ok])[0, 1]
        kept = np.mean(np.sign(a[ok]) == np.sign(b[ok]))
        print(
            f"| {pathlib.Path(directory).name} | {algorithm} | {phi.shape[0]} x {phi.shape[1]} "
            f"({np.isfinite(phi).sum()}) | {np.nanmean(np.abs(phi)):.3f} | {within:.3f} "
            f"| {between:.3f} | {corr:.2f} | {kept:.2f} |"
        )


def agent_capacity(group: list[dict]) -> str:
    config = ResultStore(pathlib.Path(group[0]["directory"])).read_config()
    rmac = config["protocol"].get("agent_configs", {}).get("rmac", {})
    return str(rmac.get("critic", {}).get("capacity", 2000))


def _per_experiment(rows: list[dict]) -> dict[tuple[str, str, int], dict[str, float]]:
    """Per directory, learner and experiment: the means over its greedy trials (``--repeat``) of
    |phi_ss| and the offset loss (upright trials only) and of the greedy return (all trials)."""
    out: dict[tuple[str, str, int], list[dict]] = {}
    for row in rows:
        out.setdefault((row["directory"], row["algorithm"], row["experiment"]), []).append(row)
    means = {}
    for key, group in out.items():
        up = [r for r in group if upright(r)]
        means[key] = {
            "|phi_ss|": float(np.mean([abs(r["phi_ss"]) for r in up])) if up else float("nan"),
            "offset loss": float(np.mean([r["offset_loss"] for r in up])) if up else float("nan"),
            "greedy return (all)": float(np.mean([r["greedy_return"] for r in group])),
        }
    return means


def paired(rows: list[dict], base_rows: list[dict]) -> None:
    """Paired t-tests, every directory against the base, experiment by experiment (each the mean
    over its greedy trials): |phi_ss| and the offset loss where both end upright, and the greedy
    return."""
    base = {(a, i): v for (_, a, i), v in _per_experiment(base_rows).items()}
    groups: dict[tuple[str, str], list[tuple[int, dict]]] = {}
    for (directory, algorithm, index), value in _per_experiment(rows).items():
        groups.setdefault((directory, algorithm), []).append((index, value))
    print(
        "\n| directory | learner | pairs | metric (mean over greedy trials) | difference (this - "
        "base) [95% CI] | p (paired t) |"
    )
    print("|---|---|---|---|---|---|")
    for (directory, algorithm), group in groups.items():
        for metric in ("|phi_ss|", "offset loss", "greedy return (all)"):
            d = np.array(
                [
                    value[metric] - base[(algorithm, index)][metric]
                    for index, value in group
                    if (algorithm, index) in base
                ]
            )
            d = d[np.isfinite(d)]
            if len(d) < 2:
                continue
            p = stats.ttest_1samp(d, 0.0).pvalue if np.ptp(d) > 0 else float("nan")
            print(
                f"| {pathlib.Path(directory).name} | {algorithm} | {len(d)} | {metric} | {_ci(d)} "
                f"| {p:.2g} |"
            )


def plot(rows: list[dict], path: str) -> None:
    """u_ss against phi_ss per experiment, with the voltage that holds the pendulum at phi."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(5.5, 4))
    groups: dict[str, list[dict]] = {}
    for row in rows:
        groups.setdefault(f"{pathlib.Path(row['directory']).name} {row['algorithm']}", []).append(
            row
        )
    for label, group in groups.items():
        ax.plot(
            [r["phi_ss"] for r in group],
            [r["u_ss"] for r in group],
            "o",
            ms=4,
            alpha=0.7,
            label=f"{label} ({len(group)})",
        )
    phi = np.linspace(-0.25, 0.25, 101)
    ax.plot(phi, -4.02 * np.sin(phi), "k--", lw=0.8, label="holding voltage -4.02 sin(phi)")
    ax.axhline(0, color="0.7", lw=0.5)
    ax.axvline(0, color="0.7", lw=0.5)
    ax.set(
        xlabel="steady-state angle phi_ss (rad, 0 = upright)",
        ylabel="steady-state voltage u_ss (V)",
        title="greedy policies after 600 trials: where they settle",
    )
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "directories",
        nargs="+",
        type=pathlib.Path,
        help="result or sweep directories, or CSV files written by --csv (their "
        "rows are summarised as they are)",
    )
    parser.add_argument("--trial", type=int, default=600)
    parser.add_argument("--last", type=int, default=30)
    parser.add_argument("--algorithms", nargs="*")
    parser.add_argument("--csv")
    parser.add_argument("--pair-with", type=pathlib.Path)
    parser.add_argument("--plot")
    parser.add_argument(
        "--set",
        action="append",
        default=[],
        metavar="ALGO.FIELD=VALUE",
        help="evaluate with this config field changed, e.g. rmac.reference.neighbours=5",
    )
    parser.add_argument(
        "--continue",
        dest="more_trials",
        type=int,
        default=0,
        metavar="N",
        help="learn N more trials from the snapshot before the greedy trial",
    )
    parser.add_argument(
        "--policy", choices=("learned", "critic-greedy", "oracle-inverse"), default="learned"
    )
    parser.add_argument(
        "--repeat",
        type=int,
        default=1,
        metavar="R",
        help="R greedy trials per experiment, one more learning trial between two",
    )
    args = parser.parse_args(argv)
    overrides = parse_sets(args.set)
    rows = []
    for path in args.directories:
        if path.suffix == ".csv":  # a table of an earlier run, redrawn
            rows += [
                r
                for r in read_csv(path)
                if not args.algorithms or r["algorithm"] in args.algorithms
            ]
            continue
        rows += [
            row
            for directory in result_dirs(path)
            for row in measure(
                directory,
                args.trial,
                args.last,
                args.algorithms,
                overrides,
                args.more_trials,
                args.policy,
                args.repeat,
            )
        ]
    summarise([r for r in rows if r["repeat"] == 0])
    if max(r["repeat"] for r in rows) > 0:
        persistence(rows)
    if args.pair_with is not None:
        base = (
            read_csv(args.pair_with)
            if args.pair_with.suffix == ".csv"
            else measure(
                args.pair_with,
                args.trial,
                args.last,
                args.algorithms,
                {},
                args.more_trials,
                "learned",
                args.repeat,
            )
        )
        paired(rows, base)
    if args.csv:
        with open(args.csv, "w", newline="") as handle:
            writer = csv.DictWriter(handle, fieldnames=FIELDS)
            writer.writeheader()
            writer.writerows(rows)
    if args.plot:
        plot(rows, args.plot)


if __name__ == "__main__":
    main(sys.argv[1:])
