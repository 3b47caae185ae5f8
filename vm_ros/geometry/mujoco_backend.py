"""MuJoCo's exact tendon geometry behind the JointGeometry interface (extra ``mujoco``).

``MujocoGeometry`` answers the same question as a fitted ``PolynomialGeometry`` (path lengths,
lengthening velocities and moment arms r = -dL/dq of every muscle at a pose of the independent
joint coordinates), computed by MuJoCo itself: ``mj_kinematics``, ``mj_comPos`` and ``mj_tendon``
give ``ten_length`` and the tendon Jacobian ``ten_J`` (dL/dqvel, sparse in MuJoCo 4.0) for every
tendon, wrapping included. This is the only module of vm_ros.geometry that imports MuJoCo.

What is what:

- muscles: actuators with a tendon transmission and MuJoCo's muscle gain or dynamics (the
  myo-sim models' muscles); the path length is the length of that tendon (m).
- coordinates: the hinge and slide joints that some muscle tendon crosses (a joint between two
  bodies of the tendon's path, or a joint of a fixed tendon), excluding joints that are dependent
  through an active joint equality (those are ``CoupledCoordinate``). A dependent joint that a
  tendon crosses makes the tendon cross the joint driving it.
- coupling: MuJoCo's joint equality holds q1 - q1_ref = a0 + a1 x + a2 x^2 + a3 x^3 + a4 x^4 with
  x = q2 - q2_ref (q_ref: the model's qpos0; obj1 the dependent joint, obj2 the driver; no obj2:
  q1 fixed at q1_ref + a0). Every evaluation sets the dependent joints from it, so
  dL/dq_indep = J_indep + J_dep * dq_dep/dq_indep (chains of dependent joints resolved in order;
  a chain that starts at a fixed-value equality is set from it, constant). Each
  ``CoupledCoordinate`` a coordinate drives holds its value over that coordinate's box
  (COUPLING_POINTS points).
- boxes: the joint range where the joint is limited; an unlimited hinge gets [-pi, pi]; an
  unlimited slide joint crossed by a muscle is an error (no natural box: give it a range).
- every other joint (free and ball joints, joints no muscle crosses) stays at the model's qpos0.

Sign conventions are those of vm_ros.geometry.paths: r = -dL/dq, tau = r^T F. Coordinates outside
their box are clamped and their velocity taken as 0, as the polynomial back end does
(``clamp=False`` evaluates MuJoCo anywhere).
"""

from __future__ import annotations

import hashlib
import math
import warnings
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vm_ros.errors import VmRosError
from vm_ros.geometry.paths import (
    COUPLING_POINTS,
    Coordinate,
    CoupledCoordinate,
    GeometryOutput,
    JointGeometry,
    clamp_to_box,
)

try:  # the optional extra: importing this module without it gives a clear error when used
    import mujoco
except ModuleNotFoundError:  # pragma: no cover - exercised only without the extra
    mujoco = None

HINGE_BOX_RAD = (-math.pi, math.pi)


class ModelLoadError(VmRosError):
    """A MuJoCo model could not be loaded or has no usable muscles; ``value`` is the source."""

    def __init__(self, value, reason: str):
        self.value = value
        self.reason = reason
        super().__init__(f"model {value!r}: {reason}")


@contextmanager
def quiet_mujoco():
    """While composing myo-sim models: their fragments warn about empty prefixes, through
    Python and through MuJoCo's own warning handler, which, left unset, prints and writes
    MUJOCO_LOG.TXT into the working directory. Both are silenced inside the block."""
    saved_handler = mujoco.get_mju_user_warning()
    mujoco.set_mju_user_warning(lambda message: None)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        mujoco.set_mju_user_warning(saved_handler)


def require_mujoco():
    if mujoco is None:
        raise VmRosError("MuJoCo is not installed: pip install 'vm_ros[mujoco]'")
    return mujoco


@dataclass(frozen=True)
class ModelSource:
    """A loaded MuJoCo model and where it came from (recorded in geometry files and logs)."""

    model: object                   # mujoco.MjModel
    name: str                       # myo-sim name, file stem, or "<MjModel>"
    file: str | None                # the XML file, if there is one
    sha256: str | None              # of the XML file, or of the composed model's XML text
    versions: dict
    kind: str = "MjModel"           # "myo-sim" (a model name), "MJCF file" or "MjModel" (given)

    def as_dict(self) -> dict:
        return {"model": self.name, "file": self.file, "sha256": self.sha256, **self.versions}

    def describe(self) -> str:
        """Which model this is, in words (for a run to say what it used)."""
        if self.kind == "myo-sim":
            return f"myo-sim {self.versions.get('myo_sim', '?')} model {self.name!r}"
        if self.kind == "MJCF file":
            return f"MJCF file {self.file}"
        return "the MjModel given"


def _versions() -> dict:
    versions = {"mujoco": mujoco.__version__}
    try:
        import myo_sim

        versions["myo_sim"] = myo_sim.__version__
    except ModuleNotFoundError:
        pass
    return versions


def load_model(source) -> ModelSource:
    """An MjModel, a path to an MJCF file, or a myo-sim model name -> ModelSource.

    A bare name (no folder part, not ending in .xml) is a myo-sim model name when myo-sim knows
    it, whatever the working directory holds (a folder ``myolegs`` there does not hide the model
    ``myolegs``); otherwise, and for anything written as a path (``./myolegs``, ``a/b.xml``), it
    is an MJCF file. ``ModelSource.describe()`` says which was used. ModelLoadError (one line)
    when the file does not compile or the name is unknown.
    """
    require_mujoco()
    if isinstance(source, mujoco.MjModel):
        return ModelSource(source, "<MjModel>", None, None, _versions())
    text = str(source)
    path = Path(text)
    if text == path.name and path.suffix.lower() != ".xml":  # a bare name
        try:
            import myo_sim
        except ModuleNotFoundError as exc:
            if not path.is_file():
                raise ModelLoadError(text, "not an MJCF file, and myo-sim (model names) is not "
                                     "installed") from exc
        else:
            try:
                with quiet_mujoco():
                    spec = myo_sim.load_spec(text)
            except ValueError as exc:  # a name myo-sim does not know
                if not path.is_file():
                    raise ModelLoadError(text, "not an MJCF file or a myo-sim model name "
                                         f"({str(exc).splitlines()[0]})") from exc
            else:
                return _myo_sim_model(myo_sim, text, spec)
    if not path.is_file():
        raise ModelLoadError(text, "no such MJCF file" + (" (a folder)" if path.is_dir() else ""))
    try:
        model = mujoco.MjModel.from_xml_path(str(path))
    except (ValueError, RuntimeError) as exc:
        raise ModelLoadError(text, f"MuJoCo cannot compile it: "
                             f"{str(exc).strip().splitlines()[0]}") from exc
    return ModelSource(model, path.stem, str(path.resolve()),
                       hashlib.sha256(path.read_bytes()).hexdigest(), _versions(), "MJCF file")


def _myo_sim_model(myo_sim, name: str, spec) -> ModelSource:
    """myo-sim's model ``name`` from its MjSpec ``spec``, compiled."""
    with quiet_mujoco():
        model = spec.compile()
        try:
            file = str(myo_sim.get_xml_path(name))
            digest = hashlib.sha256(Path(file).read_bytes()).hexdigest()
        except ValueError:  # composed from fragments: hash the composed model's XML
            file = None
            try:
                digest = hashlib.sha256(spec.to_xml().encode()).hexdigest()
            except (ValueError, RuntimeError):  # a spec MuJoCo cannot write back: no hash
                digest = None
    return ModelSource(model, name, file, digest, _versions(), "myo-sim")


def _name(model, kind, index: int) -> str:
    return mujoco.mj_id2name(model, kind, index) or f"{kind.name[6:].lower()}{index}"


def muscle_actuators(model) -> list[tuple[str, int]]:
    """(actuator name, tendon id) of every actuator with a tendon transmission and MuJoCo's
    muscle gain or muscle dynamics, in actuator order."""
    out = []
    for a in range(model.nu):
        if model.actuator_trntype[a] != mujoco.mjtTrn.mjTRN_TENDON:
            continue
        if (model.actuator_gaintype[a] == mujoco.mjtGain.mjGAIN_MUSCLE
                or model.actuator_dyntype[a] == mujoco.mjtDyn.mjDYN_MUSCLE):
            out.append((_name(model, mujoco.mjtObj.mjOBJ_ACTUATOR, a),
                        int(model.actuator_trnid[a, 0])))
    return out


@dataclass(frozen=True)
class JointCoupling:
    """One dependent joint: q - q_ref = polynomial(q_driver - q_driver_ref) (MuJoCo's joint
    equality); driver -1: held at q_ref + coefficients[0]."""

    joint: int
    driver: int
    coefficients: tuple[float, ...]   # a0..a4
    equality: str

    def value(self, x: float) -> float:
        a = self.coefficients
        return a[0] + x * (a[1] + x * (a[2] + x * (a[3] + x * a[4])))

    def slope(self, x: float) -> float:
        a = self.coefficients
        return a[1] + x * (2 * a[2] + x * (3 * a[3] + x * 4 * a[4]))


def joint_couplings(model) -> list[JointCoupling]:
    """Active joint equalities, ordered so that every driver comes before the joints it drives.

    ModelLoadError for a joint made dependent twice or a cycle of couplings."""
    by_joint = {}
    for e in range(model.neq):
        if model.eq_type[e] != mujoco.mjtEq.mjEQ_JOINT or not model.eq_active0[e]:
            continue
        joint = int(model.eq_obj1id[e])
        name = _name(model, mujoco.mjtObj.mjOBJ_EQUALITY, e)
        if joint in by_joint:
            raise ModelLoadError(name, f"joint {_name(model, mujoco.mjtObj.mjOBJ_JOINT, joint)!r}"
                                 " is made dependent by two joint equalities")
        by_joint[joint] = JointCoupling(joint, int(model.eq_obj2id[e]),
                                        tuple(float(v) for v in model.eq_data[e, :5]), name)
    ordered, done = [], set()

    def visit(joint, trail):
        if joint in done or joint not in by_joint:
            return
        if joint in trail:
            raise ModelLoadError(by_joint[joint].equality, "joint equalities form a cycle")
        visit(by_joint[joint].driver, trail | {joint})
        done.add(joint)
        ordered.append(by_joint[joint])

    for joint in sorted(by_joint):
        visit(joint, frozenset())
    return ordered


def _ancestor_joints(model, body: int) -> list[int]:
    """Joints from ``body`` up to the world, nearest first."""
    joints = []
    while body > 0:
        start, count = model.body_jntadr[body], model.body_jntnum[body]
        joints.extend(range(start + count - 1, start - 1, -1) if count > 0 else [])
        body = model.body_parentid[body]
    return joints


def tendon_joints(model, tendon: int) -> set[int]:
    """Joints a tendon crosses: for a fixed tendon, its joints; for a spatial tendon, the joints
    between the lowest common ancestor of the bodies of its sites and wrapping geoms and those
    bodies (joints above it move the whole path rigidly)."""
    start, count = model.tendon_adr[tendon], model.tendon_num[tendon]
    bodies, joints = set(), set()
    for w in range(start, start + count):
        kind, obj = int(model.wrap_type[w]), int(model.wrap_objid[w])
        if kind == mujoco.mjtWrap.mjWRAP_JOINT:
            joints.add(int(obj))
        elif kind == mujoco.mjtWrap.mjWRAP_SITE:
            bodies.add(int(model.site_bodyid[obj]))
        elif kind in (int(mujoco.mjtWrap.mjWRAP_SPHERE), int(mujoco.mjtWrap.mjWRAP_CYLINDER)):
            bodies.add(int(model.geom_bodyid[obj]))
    chains = [_ancestor_joints(model, b) for b in bodies]
    if chains:
        common = set.intersection(*(set(c) for c in chains))
        for chain in chains:
            joints.update(j for j in chain if j not in common)
    return joints


class MuscleTendons:
    """Reads the muscle tendons' lengths, velocities and dense Jacobian from an MjData.

    After ``mj_step1`` (or ``mj_fwdPosition`` / ``mj_tendon``): ``lengths(d)`` (n,) m,
    ``velocities(d)`` (n,) m/s (``ten_velocity``, after the velocity stage), ``jacobian(d)``
    (n, nv) dL/dqvel, from MuJoCo's sparse ``ten_J``.
    """

    def __init__(self, model, tendon_ids):
        self.tendon_ids = np.asarray(tendon_ids, dtype=np.int64)
        self.nv = model.nv
        rows, cols, index = [], [], []
        for i, t in enumerate(self.tendon_ids):
            adr, nnz = model.ten_J_rowadr[t], model.ten_J_rownnz[t]
            rows.extend([i] * nnz)
            cols.extend(model.ten_J_colind[adr:adr + nnz])
            index.extend(range(adr, adr + nnz))
        self._rows = np.asarray(rows, dtype=np.int64)
        self._cols = np.asarray(cols, dtype=np.int64)
        self._index = np.asarray(index, dtype=np.int64)

    def lengths(self, data) -> np.ndarray:
        return data.ten_length[self.tendon_ids]

    def velocities(self, data) -> np.ndarray:
        return data.ten_velocity[self.tendon_ids]

    def jacobian(self, data) -> np.ndarray:
        out = np.zeros((len(self.tendon_ids), self.nv))
        out[self._rows, self._cols] = data.ten_J[self._index]
        return out


class MujocoGeometry(JointGeometry):
    """Exact path lengths and moment arms from a MuJoCo model (see the module docstring).

    ``model``: an MjModel, a path to an MJCF file or a myo-sim model name. ``muscles``: a subset
    of the model's muscle names (default all). ``clamp``: clamp coordinates to their boxes as the
    polynomial back end does. Holds its own MjData; not thread-safe.

    Attributes beyond JointGeometry's: ``model``, ``data``, ``source`` (dict: model, file, sha256,
    versions), ``origin`` (which model was used, in words), ``tendon_ids``, ``joint_ids`` (of the
    coordinates), ``couplings``, ``crossed`` (per muscle, the coordinate names its tendon
    crosses), ``notes`` (choices made, one line each).
    """

    def __init__(self, model, muscles=None, clamp: bool = True):
        loaded = load_model(model)
        m = self.model = loaded.model
        self.source = loaded.as_dict()
        self.origin = loaded.describe()
        self.data = mujoco.MjData(m)
        self.clamp = clamp
        self.notes: list[str] = []
        actuators = muscle_actuators(m)
        if muscles is not None:
            wanted = list(muscles)
            have = dict(actuators)
            missing = [n for n in wanted if n not in have]
            if missing:
                raise ModelLoadError(loaded.name, f"no muscle(s) {missing} (have: "
                                     f"{', '.join(have)})")
            actuators = [(n, have[n]) for n in wanted]
        if not actuators:
            raise ModelLoadError(loaded.name, "no muscle actuators with a tendon transmission")
        self.muscle_names = tuple(n for n, _ in actuators)
        self.tendon_ids = np.array([t for _, t in actuators], dtype=np.int64)
        self.couplings = tuple(joint_couplings(m))
        driver_of = {c.joint: c.driver for c in self.couplings}

        def root(joint):
            while joint in driver_of:
                joint = driver_of[joint]
            return joint

        sliding = (int(mujoco.mjtJoint.mjJNT_HINGE), int(mujoco.mjtJoint.mjJNT_SLIDE))
        crossed_joints = []
        for t in self.tendon_ids:
            independent = set()
            for j in tendon_joints(m, int(t)):
                r = root(j)
                if r < 0:
                    continue  # held by a fixed-value equality
                if int(m.jnt_type[r]) in sliding:
                    independent.add(r)
                else:
                    note = (f"{_name(m, mujoco.mjtObj.mjOBJ_JOINT, r)}: not a hinge or slide "
                            "joint, held at qpos0")
                    if note not in self.notes:
                        self.notes.append(note)
            crossed_joints.append(independent)
        self.joint_ids = np.array(sorted(set().union(*crossed_joints)), dtype=np.int64)
        self.coordinates = tuple(self._coordinate(int(j)) for j in self.joint_ids)
        names = self.coordinate_names
        position = {int(j): i for i, j in enumerate(self.joint_ids)}
        self.crossed = {n: tuple(names[position[j]] for j in sorted(c))
                        for n, c in zip(self.muscle_names, crossed_joints, strict=True)}
        # dependent joints driven (through chains) by a coordinate or held by a fixed-value
        # equality (root -1), in evaluation order
        self._dependents = [c for c in self.couplings
                            if root(c.joint) in position or root(c.joint) < 0]
        self._qadr = m.jnt_qposadr[self.joint_ids]
        self._dofadr = m.jnt_dofadr[self.joint_ids]
        self._dep_qadr = np.array([m.jnt_qposadr[c.joint] for c in self._dependents], np.int64)
        self._dep_dofadr = np.array([m.jnt_dofadr[c.joint] for c in self._dependents], np.int64)
        self._position = position
        self.tendons = MuscleTendons(m, self.tendon_ids)
        self._lower, self._upper = self.lower, self.upper
        self.coupled = self._coupled_coordinates(root)

    def _coupled_coordinates(self, root) -> tuple[CoupledCoordinate, ...]:
        """One per dependent joint; for one a coordinate drives, its value over that
        coordinate's box (COUPLING_POINTS points; the polynomials composed along a chain)."""
        m = self.model
        grid = np.linspace(self._lower, self._upper, COUPLING_POINTS)  # (points, n_q)
        table = np.empty((len(grid), len(self._dependents)))
        for i, q in enumerate(grid):
            self.set_pose(q)
            table[i] = self.data.qpos[self._dep_qadr]
        out = []
        for k, c in enumerate(self._dependents):
            name = _name(m, mujoco.mjtObj.mjOBJ_JOINT, c.joint)
            if root(c.joint) < 0:
                out.append(CoupledCoordinate(name, (), self._coupling_note(c)))
                continue
            j = self._position[root(c.joint)]
            hinge = m.jnt_type[c.joint] == mujoco.mjtJoint.mjJNT_HINGE
            out.append(CoupledCoordinate(name, (self.coordinate_names[j],),
                                         self._coupling_note(c), "rad" if hinge else "m",
                                         tuple(grid[:, j]), tuple(table[:, k])))
        return tuple(out)

    def _coordinate(self, joint: int) -> Coordinate:
        m = self.model
        name = _name(m, mujoco.mjtObj.mjOBJ_JOINT, joint)
        hinge = m.jnt_type[joint] == mujoco.mjtJoint.mjJNT_HINGE
        if m.jnt_limited[joint]:
            lower, upper = (float(v) for v in m.jnt_range[joint])
        elif hinge:
            lower, upper = HINGE_BOX_RAD
            self.notes.append(f"{name}: unlimited hinge, box [-pi, pi]")
        else:
            raise ModelLoadError(self.source["model"], f"slide joint {name!r} is crossed by a "
                                 "muscle but has no range: give it one (range=...)")
        return Coordinate(name, "rad" if hinge else "m", lower, upper)

    def _coupling_note(self, c: JointCoupling) -> str:
        m = self.model
        driver = (_name(m, mujoco.mjtObj.mjOBJ_JOINT, c.driver) if c.driver >= 0 else None)
        poly = ", ".join(f"{a:.6g}" for a in c.coefficients)
        if driver is None:
            return f"MuJoCo joint equality {c.equality!r}: fixed at qpos0 + {c.coefficients[0]:.6g}"
        return (f"MuJoCo joint equality {c.equality!r}: q - q0 = polycoef(q_{driver} - q0_"
                f"{driver}), polycoef [{poly}]")

    def _couple(self, qpos, write: bool) -> np.ndarray:
        """dq_dep/dq (n_dependents, n_q) at the driver positions in qpos; with ``write`` the
        dependent joints' positions are first set from their polynomials (in chain order)."""
        m = self.model
        n_q = len(self.joint_ids)
        slopes = {int(j): row for j, row in zip(self.joint_ids, np.eye(n_q), strict=True)}
        out = np.zeros((len(self._dependents), n_q))
        for k, c in enumerate(self._dependents):
            adr = m.jnt_qposadr[c.joint]
            if c.driver < 0:
                if write:
                    qpos[adr] = m.qpos0[adr] + c.coefficients[0]
            else:
                dadr = m.jnt_qposadr[c.driver]
                x = qpos[dadr] - m.qpos0[dadr]
                if write:
                    qpos[adr] = m.qpos0[adr] + c.value(x)
                out[k] = c.slope(x) * slopes[c.driver]
            slopes[c.joint] = out[k]
        return out

    def set_pose(self, q) -> np.ndarray:
        """Put the coordinates q (n_q,) and the joints that depend on them into ``data.qpos``
        (every other joint at qpos0); returns dq_dep/dq (n_dependents, n_q)."""
        qpos = self.data.qpos
        qpos[:] = self.model.qpos0
        qpos[self._qadr] = q
        return self._couple(qpos, write=True)

    def velocity_map(self, qpos) -> np.ndarray:
        """G (nv, n_q): dof velocities per coordinate velocity at a pose (qvel = G qdot for the
        coordinates and their dependent joints), from the drivers' positions in ``qpos``. A
        simulation's generalized forces map to coordinate torques as G^T qfrc."""
        out = np.zeros((self.model.nv, len(self.joint_ids)))
        out[self._dofadr, np.arange(len(self.joint_ids))] = 1.0
        if len(self._dependents):
            out[self._dep_dofadr] = self._couple(np.asarray(qpos, dtype=float), write=False)
        return out

    def lengths_and_gradients(self, q) -> tuple[np.ndarray, np.ndarray]:
        """(L (n_muscles,), dL/dq (n_muscles, n_q)) at q, no clamping (for fitting and tests)."""
        dep = self.set_pose(np.asarray(q, dtype=float))
        m, d = self.model, self.data
        mujoco.mj_kinematics(m, d)
        mujoco.mj_comPos(m, d)
        mujoco.mj_tendon(m, d)
        jac = self.tendons.jacobian(d)
        gradient = jac[:, self._dofadr]
        if len(self._dependents):
            gradient = gradient + jac[:, self._dep_dofadr] @ dep
        return self.tendons.lengths(d).copy(), gradient

    def evaluate(self, q, qdot=None) -> GeometryOutput:
        q, qdot = self.check_pose(q, qdot)
        if self.clamp:
            q_used, qdot_used, clamped = clamp_to_box(q, qdot, self._lower, self._upper)
        else:
            q_used, qdot_used, clamped = q, qdot, np.zeros(len(q), bool)
        length, gradient = self.lengths_and_gradients(q_used)
        return GeometryOutput(length, gradient @ qdot_used, -gradient, q_used, qdot_used,
                              clamped)

    @property
    def qpos_addresses(self) -> np.ndarray:
        """Index of each coordinate in qpos (n_q,)."""
        return self._qadr.copy()

    @property
    def dof_addresses(self) -> np.ndarray:
        """Index of each coordinate in qvel / qfrc (n_q,)."""
        return self._dofadr.copy()


__all__ = ["HINGE_BOX_RAD", "JointCoupling", "ModelLoadError", "ModelSource", "MujocoGeometry",
           "MuscleTendons", "joint_couplings", "load_model", "muscle_actuators",
           "require_mujoco", "tendon_joints"]
