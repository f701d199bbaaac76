"""``NavEnvironment``: composer's environment with one physics-state check per control step."""

from __future__ import annotations

import logging
from collections.abc import Iterator

import mujoco
import numpy as np
from dm_control import composer
from dm_control.rl import control

__all__ = ["NavEnvironment"]

_WARNING_NAMES = list(mujoco.mjtWarning.__members__)
_LOG = logging.getLogger(__name__)


class NavEnvironment(composer.Environment):
    """A ``composer.Environment`` whose substeps skip composer's per-substep state check.

    ``Physics.step`` wraps every ``mj_step`` in ``check_invalid_state`` (copy and compare
    MuJoCo's warning counters through a context manager); at five substeps per control step
    that is about a tenth of a whole control step of this task. Here the counters are
    snapshotted before the first substep and compared after the last one, raising the same
    ``PhysicsError`` inside composer's own handler (or logging it, as ``Physics`` does under
    ``suppress_physics_errors``). Hooks, observation updates, rewards and termination are
    composer's. With ``legacy_step=True`` every substep takes composer's path unchanged.

    A task that offers ``fused_substeps`` (:class:`mjnav.tasks.nav.CrowdNavTask`) runs all the
    substeps of a step at its first one (``run_substeps``, one compiled call, same results)
    when no entity or extra hook wants the substeps; composer's observation updates between
    substeps still happen (they read the task's observation buffer, which only changes after
    the step).

    :meth:`step_task` runs only the task's part of a step, for the Gymnasium adapter, which
    reads its outputs from the task; :meth:`step_stages` runs it stage by stage.

    Relies on composer internals (``_hooks`` and its hook lists, ``_physics``, ``_n_sub_steps``) of the pinned
    dm-control release; ``tests/envs/test_environment.py`` checks the rollouts match.
    """

    def step(self, action):
        """One control step (see ``composer.Environment.step``)."""
        self._substep_index = 0
        return super().step(action)

    def _substep(self, action) -> None:
        k = self._substep_index
        if k == 0:  # the pointers stay valid for the step (no recompile mid-step)
            physics = self._physics
            self._legacy = physics.legacy_step
            self._model_ptr, self._data_ptr = physics.model.ptr, physics.data.ptr
            self._warnings = physics.data.warning.number  # a view: read again after the last substep
            self._warnings_before = self._warnings.tobytes()
            self._fused = not self._legacy and self._can_fuse()
        if self._legacy:
            super()._substep(action)
            return
        if self._fused:
            if k == 0:
                self._task.run_substeps(self._physics_proxy)
        else:
            self._hooks.before_substep(self._physics_proxy, action, self._random_state)
            mujoco.mj_step(self._model_ptr, self._data_ptr)
            self._hooks.after_substep(self._physics_proxy, self._random_state)
        self._substep_index = k = k + 1
        if k == self._n_sub_steps and self._warnings.tobytes() != self._warnings_before:
            self._raise_warnings(self._physics, self._warnings, self._warnings_before)

    def can_step_task(self) -> bool:
        """Whether :meth:`step_task` may stand in for :meth:`step` for a caller that reads the task.

        True when nothing but the task takes part in a step (no entity or extra step hooks),
        its substeps fuse, physics errors raise and there is no time limit.
        """
        return (not self._physics.legacy_step and self._raise_exception_on_physics_error
                and self._time_limit == float("inf") and self._can_fuse()
                and self._only_task_hooks(self._hooks._before_step, self._hooks._after_step))

    def step_task(self, action) -> None:
        """One control step through the task's own hooks, without composer's step machinery.

        The task's before-step hook, its fused substeps and its after-step hook, exactly as
        :meth:`step` calls them when :meth:`can_step_task` holds; no observation updater and no
        ``TimeStep``: read the reward, outcome and observation from the task. A MuJoCo warning
        raises ``PhysicsError`` as :meth:`step` does. Composer's own bookkeeping (observation
        buffers, the pending reset after a last step) is not advanced, so do not mix this with
        :meth:`step` within an episode.
        """
        for _ in self.step_stages(action):
            pass

    def step_stages(self, action) -> Iterator[None]:
        """:meth:`step_task` in stages: each ``next()`` runs one, the generator ends with the step.

        The stages are the task's before-step hook, its substeps, and its after-step hook (in two,
        :meth:`~mjnav.tasks.nav.CrowdNavTask.sense` and ``score``, when the task
        ``splits_after_step``). An environment's stages only touch its own state, so the
        environments of a process may be stepped stage by stage (every environment's first stage,
        then every second ...) with the results of stepping them in turn, while each stage's
        code and shared data stay in the cache (:class:`mjnav.envs.workers._EnvGroup`).
        """
        task, physics, proxy = self._task, self._physics, self._physics_proxy
        task.before_step(proxy, action, self._random_state)
        yield
        warnings = physics.data.ptr.warning.number
        before = warnings.tobytes()
        task.run_substeps(proxy)
        if warnings.tobytes() != before:
            self._raise_warnings(physics, warnings, before)
        yield
        if getattr(task, "splits_after_step", False):
            task.sense(proxy)
            yield
            task.score(proxy)
        else:
            task.after_step(proxy, self._random_state)

    def _can_fuse(self) -> bool:
        """Whether the task may run the step's substeps at once: it offers to, no other substep hooks."""
        if not getattr(self._task, "fused_substeps", False):
            return False
        return self._only_task_hooks(self._hooks._before_substep, self._hooks._after_substep)

    @staticmethod
    def _only_task_hooks(*hooks) -> bool:
        """Whether none of composer's hook lists ``hooks`` holds an entity or extra hook."""
        return not any(hook.entity_hooks or hook.extra_hooks for hook in hooks)

    def _raise_warnings(self, physics, warnings: np.ndarray, before: bytes) -> None:
        """Raises (or logs) a ``PhysicsError`` for MuJoCo warnings raised since ``before``.

        Args:
            physics: The physics.
            warnings: ``data.warning.number`` (a live view).
            before: Its bytes at the start of the step.
        """
        new = warnings > np.frombuffer(before, dtype=warnings.dtype)
        if not new.any():  # counters only fell (a reset inside a hook): nothing was raised
            return
        names = ", ".join(np.compress(new, _WARNING_NAMES))
        message = f"Physics state is invalid. Warning(s) raised: {names}"
        if getattr(physics, "_warnings_cause_exception", True):
            raise control.PhysicsError(message)
        _LOG.warning(message)
