"""Multi-agent learning over the distributed loop (PettingZoo and vectorised envs).

``SwarmEnv`` is a PettingZoo ``ParallelEnv`` of one scene; ``SwarmVec`` the
batched array API over many isolated scenes with physics batched across them;
``SwarmVectorEnv`` its Gymnasium vector adapter; :mod:`sigma_des.env.sb3` its
Stable-Baselines3 ``VecEnv`` (the ``learn`` extra, imported on its own). Tasks,
observations, actions and rewards: :mod:`sigma_des.env.tasks`; hand-written
controllers of the ``tight`` task: :mod:`sigma_des.env.controllers`; the CEM
learner: :mod:`sigma_des.env.learn`; how to train: ``docs/howto/train-agent.md``.
"""

from sigma_des.env.parallel import SwarmEnv
from sigma_des.env.tasks import TASKS, FormationTask, GoalTask, TightTask
from sigma_des.env.vector import SwarmVec, SwarmVectorEnv

__all__ = ["SwarmEnv", "SwarmVec", "SwarmVectorEnv", "TASKS", "FormationTask", "GoalTask",
           "TightTask"]
