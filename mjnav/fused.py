"""All physics substeps of one control period in one compiled call.

Between two control steps the simulation does, per physics substep: place the pedestrians
(mocap), write the robot's tracking force, note a robot contact, ``mj_step``. In Python that
loop costs about as much as the ``mj_step`` calls themselves. :class:`FusedStepper` runs it in
one numba kernel that calls MuJoCo's own ``mj_step`` through its C address, with the same
floating-point operations in the same order, so the results are bit-identical to the Python
loop (``tests/test_fused.py``).

A MuJoCo error inside ``mj_step`` (``mju_error``: an exhausted arena, a raising Python
callback) cannot pass through the compiled frame, so the kernel is not used while any
``mjcb_*`` callback is installed (:func:`callbacks_installed`); for the small scenes of this
package the arena is far from full.

The kernel reads one field of ``mjData`` that the Python bindings expose only as a scalar
(``ncon``); its offset comes from MuJoCo's own struct description (``mujoco.introspect``) laid
out by ``ctypes`` and is checked against the bindings on a probe model. Anything that does not
check out (no shared library found, a layout mismatch, a step that differs from
``mujoco.mj_step``) leaves :func:`fused_support` with the reason, and callers use the Python
loop instead.
"""

from __future__ import annotations

import ctypes
import functools
import glob
import os

import mujoco
import numba
import numpy as np
from llvmlite import ir
from mujoco.introspect import ast_nodes, structs
from numba import types
from numba.extending import intrinsic

from mjnav.control import dynamics

__all__ = ["FusedStepper", "callbacks_installed", "fused_support"]

_CALLBACK_GETTERS = tuple(getattr(mujoco, name) for name in dir(mujoco) if name.startswith("get_mjcb_"))
_LIBRARY_PATTERNS = ("libmujoco.so*", "libmujoco*.dylib", "mujoco.dll")
_PRIMITIVES = {
    "int": ctypes.c_int, "unsigned int": ctypes.c_uint, "float": ctypes.c_float, "mjtNum": ctypes.c_double,
    "mjtSize": ctypes.c_int64, "size_t": ctypes.c_size_t, "uintptr_t": ctypes.c_size_t, "uint64_t": ctypes.c_uint64,
    "mjtBool": ctypes.c_ubyte, "mjtByte": ctypes.c_ubyte, "char": ctypes.c_char,
}


@intrinsic
def _call_step(typingctx, fn, model, data):
    """Calls ``void fn(const mjModel*, mjData*)`` given the three addresses as integers."""
    del typingctx

    def codegen(context, builder, signature, args):
        del signature
        fnty = ir.FunctionType(ir.VoidType(), [ir.IntType(64), ir.IntType(64)])
        builder.call(builder.inttoptr(args[0], fnty.as_pointer()), [args[1], args[2]])
        return context.get_dummy_value()

    return types.void(types.uint64, types.uint64, types.uint64), codegen


#: The tracking law and clamp of :mod:`mjnav.control.dynamics`, compiled for the kernel.
_clamp = numba.njit(cache=True)(dynamics.clamp)
_tracking_force = numba.njit(cache=True)(dynamics.tracking_force)


@numba.njit(cache=True)
def _run(step, model, data, start, check, ncon, plan, track, mocap, rows, qpos, qvel, ctrl, index, gains):
    """Substeps ``start..n-1``: pedestrians, tracking force, ``mj_step``.

    Returns ``n``, or the substep ``k >= 1`` before which a contact was found (when ``check``;
    the caller reads it and resumes at ``k`` with ``check`` False for that one substep).
    """
    n = plan.shape[0]
    mass, kv, kp, fmax = gains[0], gains[1], gains[2], gains[3]
    for k in range(start, n):
        if check and k > 0 and ncon[0] > 0:
            return k
        check = True
        for i in range(rows.shape[0]):
            mocap[rows[i], 0] = track[k, i, 0]
            mocap[rows[i], 1] = track[k, i, 1]
        fx = _tracking_force(plan[k, 0], plan[k, 2], qvel[index[0]], plan[k, 4], qpos[index[2]], kv, kp)
        fy = _tracking_force(plan[k, 1], plan[k, 3], qvel[index[1]], plan[k, 5], qpos[index[3]], kv, kp)
        ctrl[index[4]] = _clamp(mass * fx, fmax)
        ctrl[index[5]] = _clamp(mass * fy, fmax)
        _call_step(step, model, data)
    return n


def _ctype(decl_type, cache: dict) -> type:
    """The ctypes type of an introspected C type (pointers as ``void*``)."""
    kind = type(decl_type).__name__
    if kind == "PointerType":
        return ctypes.c_void_p
    if kind == "ArrayType":
        inner = _ctype(decl_type.inner_type, cache)
        for extent in reversed(decl_type.extents):
            inner = inner * extent
        return inner
    name = decl_type.name
    if name in _PRIMITIVES:
        return _PRIMITIVES[name]
    if name not in cache:
        fields = [(f.name, _ctype(f.type, cache)) for f in structs.STRUCTS[name].fields]
        cache[name] = type(name, (ctypes.Structure,), {"_fields_": fields})
    return cache[name]


def _ncon_offset() -> int:
    """Byte offset of ``mjData.ncon`` from MuJoCo's struct description."""

    return _ctype(ast_nodes.ValueType("mjData"), {}).ncon.offset


def _step_address() -> int:
    """C address of ``mj_step`` in the MuJoCo library that the bindings load."""
    folder = os.path.dirname(mujoco.__file__)
    paths = sorted(p for pattern in _LIBRARY_PATTERNS for p in glob.glob(os.path.join(folder, pattern)))
    if not paths:
        raise RuntimeError(f"no MuJoCo shared library in {folder}")
    library = ctypes.CDLL(paths[0])
    library.mj_version.restype = ctypes.c_int
    if library.mj_version() != mujoco.mj_version():
        raise RuntimeError(f"{paths[0]} is MuJoCo {library.mj_version()}, the bindings {mujoco.mj_version()}")
    return ctypes.cast(library.mj_step, ctypes.c_void_p).value


_PROBE = """
<mujoco>
  <worldbody>
    <geom type="plane" size="2 2 0.1"/>
    <body pos="0 0 0.2"><freejoint name="box"/><geom type="box" size="0.1 0.1 0.1"/></body>
  </worldbody>
  <actuator>
    <motor joint="box" gear="1 0 0 0 0 0"/>
    <motor joint="box" gear="0 0 1 0 0 0"/>
  </actuator>
</mujoco>
"""


def _probe(step: int, offset: int) -> None:
    """Checks the ``ncon`` view and a fused step against the bindings on a small model."""
    model = mujoco.MjModel.from_xml_string(_PROBE)
    data, twin = mujoco.MjData(model), mujoco.MjData(model)
    ncon = _field_view(data, offset)
    counts = []
    for height in (0.2, 0.099, 0.2):  # apart, resting on four corners, apart again
        data.qpos[2] = height
        mujoco.mj_forward(model, data)
        counts.append((int(ncon[0]), data.ncon))
    if any(a != b for a, b in counts) or counts[1][1] == 0:
        raise RuntimeError(f"mjData.ncon offset {offset} reads {counts} (view, bindings)")
    data.qpos[2] = twin.qpos[2] = 0.099
    twin.ctrl[:] = 0.5, 0.0  # what the kernel writes below
    plan = np.array([[0.05, 0.0, 0.0, 0.0, 0.0, 0.0]])
    args = (np.zeros((1, 0, 2)), data.mocap_pos, np.zeros(0, np.int64), data.qpos, data.qvel, data.ctrl,
            np.array([0, 1, 0, 1, 0, 1], np.int64), np.array([10.0, 0.0, 0.0, 100.0]))
    _run(step, model._address, data._address, 0, True, ncon, plan, *args)
    mujoco.mj_step(model, twin)
    if not (np.array_equal(data.qpos, twin.qpos) and np.array_equal(data.qvel, twin.qvel)):
        raise RuntimeError("a step through the C address differs from mujoco.mj_step")


def _field_view(data: mujoco.MjData, offset: int) -> np.ndarray:
    """A (1,) int32 view of the ``mjData`` field at ``offset`` bytes (lives as long as ``data``)."""
    return np.frombuffer((ctypes.c_char * 4).from_address(data._address + offset), dtype=np.int32)


def callbacks_installed() -> bool:
    """Whether any MuJoCo callback (``mjcb_*``) is installed.

    A Python callback that raises inside ``mj_step`` ends in ``mju_error``, which the bindings
    turn into a Python exception only when they made the call; callers then use the Python loop.
    """
    for get in _CALLBACK_GETTERS:
        if get() is not None:
            return True
    return False


def fused_support() -> tuple[int, int] | str:
    """``(mj_step address, ncon offset)``, or why fused substeps are unavailable here.

    Checked once per process (with no MuJoCo callback installed: the probe steps a model).
    """
    if callbacks_installed():
        return "a MuJoCo callback (mjcb_*) is installed"
    return _checked_support()


@functools.cache
def _checked_support() -> tuple[int, int] | str:
    try:
        step, offset = _step_address(), _ncon_offset()
        _probe(step, offset)
    except Exception as exc:  # noqa: BLE001 - any failure means: use the Python loop
        return f"{type(exc).__name__}: {exc}"
    return step, offset


class FusedStepper:
    """Runs a period's substeps for one ``MjModel``/``MjData`` pair in one compiled call."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData) -> None:
        """Raises RuntimeError (with the reason) when :func:`fused_support` fails."""
        support = fused_support()
        if isinstance(support, str):
            raise RuntimeError(support)  # noqa: TRY004 - a failed check, not a wrong argument
        self._step, offset = support
        self.model, self.data = model, data
        self._addresses = (model._address, data._address)
        self._ncon = _field_view(data, offset)
        self._arrays = (data.mocap_pos, data.qpos, data.qvel, data.ctrl)

    def run(self, start: int, check: bool, plan: np.ndarray, track: np.ndarray, rows: np.ndarray,
            index: np.ndarray, gains: np.ndarray) -> int:
        """Substeps ``start`` to ``len(plan) - 1``, or up to a contact (see below).

        Args:
            start: First substep of the period to run.
            check: Stop before a substep ``k >= 1`` (``k > start`` if False) when the previous
                ``mj_step`` found contacts, returning ``k``.
            plan: (n, 6) ``[ux, uy, vx, vy, px, py]`` per substep (robot tracking plan).
            track: (n, P, 2) pedestrian positions per substep.
            rows: (P,) int64 mocap rows of the pedestrians.
            index: (6,) int64 ``[dof x, dof y, qpos x, qpos y, ctrl x, ctrl y]`` of the robot.
            gains: (4,) ``[mass, kv, kp, force_max]`` of the tracking force.

        Returns:
            ``n`` after the last substep, else the substep before which contacts were found.
        """
        mocap, qpos, qvel, ctrl = self._arrays
        return _run(self._step, *self._addresses, start, check, self._ncon, plan, track, mocap, rows,
                    qpos, qvel, ctrl, index, gains)
