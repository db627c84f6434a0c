"""Moved: the trial loop is :mod:`rmac_mj.rollout`; this name keeps older imports working."""

from rmac_mj.rollout import (action_space_of, learner_state_of, n_sub_steps,  # noqa: F401
                             run_trial, state_of, state_space_of, steps_per_trial, trial_seconds)
