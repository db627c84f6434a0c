"""Learner settings for tests that run every registered learner.

SB3's defaults update 256-transition batches through networks of 256 units at every control step
(about 10 ms a step here); tests that only need some learning run the baselines small.
"""

QUICK = {
    "sb3-sac": {"net_arch": [16, 16], "batch_size": 16, "learning_starts": 20, "train_freq": 20},
    "sb3-td3": {"net_arch": [16, 16], "batch_size": 16, "learning_starts": 20, "train_freq": 20},
    "sb3-ppo": {"net_arch": [16, 16], "n_steps": 64, "batch_size": 32, "n_epochs": 1},
    "sb3-crossq": {
        "net_arch": [16, 16],
        "critic_net_arch": [16, 16],
        "batch_size": 16,
        "learning_starts": 20,
        "train_freq": 20,
    },
}


def quick_config(algorithm: str) -> dict:
    """Overrides of ``algorithm``'s defaults for a fast test (none for the paper's learners)."""
    return dict(QUICK.get(algorithm, {}))
