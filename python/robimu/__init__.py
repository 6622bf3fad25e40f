"""robimu: joint calibration of a robot arm and an IMU, for Python.

The ``robimu`` program's pipelines as a library: load or simulate a session,
check it, calibrate it, diagnose it, export the result. Every call runs the
same Rust code as the command of the same name, with its options named like
the command's flags (``--knot-spacing`` is ``knot_spacing=``), and writes the
same files: ``Result.save`` writes the result.json that ``robimu calibrate``
writes, to the bit.

Errors are exceptions whose text is the program's message: ``BadInputError``
(the input cannot be used), ``NotConvergedError`` (the estimation failed),
``WriteError`` (a file could not be written), all ``RobimuError``. The
program's warnings are ``RobimuWarning`` warnings. Long calls release the
GIL and stop at Ctrl-C (``KeyboardInterrupt``).

>>> import robimu
>>> s = robimu.simulate("aubo_i5", duration=60, seed=1)
>>> r = robimu.calibrate(s)
>>> print(r.verdict)  # doctest: +SKIP
good
"""

from __future__ import annotations

import json
import os
import shutil
import sys
import tempfile
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import (
    Any,
    Callable,
    Dict,
    Iterable,
    List,
    Mapping,
    Optional,
    Sequence,
    Tuple,
    Union,
)

import numpy as np

from . import _native
from ._native import BadInputError, NotConvergedError, RobimuError, WriteError

__version__: str = _native.__version__

__all__ = [
    "BadInputError",
    "CheckReport",
    "Diagnosis",
    "ImuSamples",
    "NotConvergedError",
    "Parameter",
    "Plan",
    "Result",
    "RobimuError",
    "RobimuWarning",
    "RobotInfo",
    "Session",
    "Verdict",
    "WriteError",
    "calibrate",
    "check",
    "diagnose",
    "export",
    "plan",
    "robots",
    "simulate",
]

PathLike = Union[str, "os.PathLike[str]"]
Progress = Union[None, bool, Callable[[str], Any]]


class RobimuWarning(UserWarning):
    """A warning the ``robimu`` program prints as ``warning: …``."""


# -- flags ------------------------------------------------------------------


def _text(value: Any) -> str:
    """One flag value as the program reads it (floats exactly)."""
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return str(value)


def _flags(**options: Any) -> List[str]:
    """Keyword options as the program's flags: ``name=value`` is
    ``--name=value`` (underscores as dashes), ``True`` the bare flag,
    ``None``/``False`` nothing, a list one flag per item."""
    args: List[str] = []
    for name, value in options.items():
        if value is None or value is False:
            continue
        flag = "--" + name.replace("_", "-")
        if value is True:
            args.append(flag)
        elif isinstance(value, (list, tuple)):
            args.extend(f"{flag}={_text(v)}" for v in value)
        else:
            args.append(f"{flag}={_text(value)}")
    return args


def _names(value: Union[None, str, Iterable[str]]) -> Optional[List[str]]:
    """A comma-separated string or a list of names."""
    if value is None:
        return None
    if isinstance(value, str):
        return [v for v in value.split(",") if v.strip()]
    return [str(v) for v in value]


def _imu_positions(value: Any) -> Optional[List[str]]:
    """``{J: (x, y, z)}``, ``[(J, (x, y, z))]`` or ``["J=X,Y,Z"]``."""
    if value is None:
        return None
    items = value.items() if isinstance(value, Mapping) else value
    out = []
    for item in items:
        if isinstance(item, str):
            out.append(item)
        else:
            j, xyz = item
            out.append(f"{int(j)}=" + ",".join(_text(float(c)) for c in xyz))
    return out


def _progress(progress: Progress) -> Optional[Callable[[str], Any]]:
    if progress is True:
        return lambda line: print(line, file=sys.stderr, flush=True)
    if progress is None or progress is False:
        return None
    return progress


def _warn(messages: Iterable[str]) -> None:
    for m in messages:
        warnings.warn(m, RobimuWarning, stacklevel=3)


def _read_only(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


# -- sessions ---------------------------------------------------------------


@dataclass(frozen=True)
class ImuSamples:
    """One IMU's samples (imu.csv or imu<J>.csv)."""

    t: np.ndarray
    """Times, s (n)."""
    accel: np.ndarray
    """Specific force ax, ay, az, m/s² (n × 3)."""
    gyro: np.ndarray
    """Angular rate gx, gy, gz, rad/s (n × 3)."""
    temp: Optional[np.ndarray]
    """Temperature, °C (n), when the file has a ``temp_c`` column."""


class Session:
    """A recording (or a simulation) in memory: session.toml, joints.csv,
    imu.csv, …, with the robot it names. The samples are read-only NumPy
    arrays; ``save`` writes the session's files as they were read."""

    def __init__(self, native: Any, summary: Optional[str] = None, path: Optional[Path] = None):
        self._native = native
        self._path = path
        self._joints: Optional[Tuple[np.ndarray, np.ndarray]] = None
        self._imus: Dict[int, ImuSamples] = {}
        self.summary: Optional[str] = summary
        """What ``robimu simulate`` printed, for a simulated session."""

    @classmethod
    def load(cls, path: PathLike) -> "Session":
        """Read the session directory ``path`` and the robot it names (the
        checks and messages of ``robimu calibrate``'s loading)."""
        p = Path(path)
        return cls(_native.NativeSession.load(os.fspath(p)), path=p)

    def save(self, path: PathLike) -> Path:
        """Write the session's files into the directory ``path`` (created
        when missing); returns it."""
        p = Path(path)
        self._native.save(os.fspath(p))
        return p

    @property
    def path(self) -> Optional[Path]:
        """The directory the session was read from (``None`` for a
        simulation written to a temporary directory)."""
        return self._path

    @property
    def robot(self) -> str:
        """The robot's name."""
        return self._native.robot

    @property
    def robot_spec(self) -> str:
        """session.toml's ``robot``: a built-in name or a URDF path."""
        return self._native.robot_spec

    @property
    def dof(self) -> int:
        """The robot's joint count."""
        return self._native.dof

    @property
    def n_imus(self) -> int:
        """The number of IMUs (imu.csv, imu1.csv, …)."""
        return self._native.n_imus

    @property
    def notes(self) -> Optional[str]:
        """session.toml's ``notes``."""
        return self._native.notes

    def _joint_arrays(self) -> Tuple[np.ndarray, np.ndarray]:
        if self._joints is None:
            t, q = self._native.joints()
            self._joints = (_read_only(t), _read_only(q))
        return self._joints

    @property
    def joint_t(self) -> np.ndarray:
        """joints.csv's times, s (n)."""
        return self._joint_arrays()[0]

    @property
    def joints(self) -> np.ndarray:
        """joints.csv's joint angles, rad (n × dof)."""
        return self._joint_arrays()[1]

    @property
    def joint_columns(self) -> List[str]:
        """joints.csv's column names after ``t`` (q1 … qn)."""
        return list(self._native.joint_columns)

    def imu(self, j: int = 0) -> ImuSamples:
        """IMU ``j``'s samples (0: imu.csv, J ≥ 1: imu<J>.csv)."""
        if j not in self._imus:
            t, z, temp = self._native.imu(j)
            self._imus[j] = ImuSamples(
                t=_read_only(t),
                accel=_read_only(z[:, :3]),
                gyro=_read_only(z[:, 3:]),
                temp=None if temp is None else _read_only(temp),
            )
        return self._imus[j]

    @property
    def tracker(self) -> Optional[Tuple[np.ndarray, np.ndarray]]:
        """tracker.csv: times (s) and poses (n × 7: px, py, pz in m, qw, qx,
        qy, qz), when the session has one."""
        out = self._native.tracker()
        return None if out is None else (_read_only(out[0]), _read_only(out[1]))

    @property
    def truth(self) -> Optional[Dict[str, float]]:
        """truth.toml's parameters by name (SI), for a simulated session."""
        values = self._native.truth()
        return None if values is None else dict(values)

    def __repr__(self) -> str:
        where = f" from {self._path}" if self._path else ""
        return (
            f"<robimu.Session{where}: robot {self.robot}, {self.n_imus} IMU"
            f"{'s' if self.n_imus != 1 else ''}>"
        )


def _session(session: Union[Session, PathLike]) -> Session:
    return session if isinstance(session, Session) else Session.load(session)


class _SessionDir:
    """The session's directory for a call that reads one: its own when it
    was read from one that still exists, else a temporary copy."""

    def __init__(self, session: Union[Session, PathLike]):
        self.session = session
        self.tmp: Optional[str] = None

    def __enter__(self) -> Path:
        if not isinstance(self.session, Session):
            return Path(self.session)
        self.tmp = tempfile.mkdtemp(prefix="robimu-")
        return self.session.save(Path(self.tmp) / "session")

    def __exit__(self, *exc: Any) -> None:
        if self.tmp is not None:
            shutil.rmtree(self.tmp, ignore_errors=True)


# -- check ------------------------------------------------------------------


class CheckReport:
    """``robimu check``'s report: each finding with its severity, and the
    fatal findings' error (the program's exit status)."""

    def __init__(self, data: Dict[str, Any], table: str, fatal: Optional[str]):
        self.data = data
        """The report as ``robimu check --json`` writes it."""
        self.table = table
        """The table the program prints."""
        self.fatal = fatal
        """The error the program ends with when a finding is fatal, else ``None``."""

    @property
    def ok(self) -> bool:
        """No fatal finding: the session can be calibrated."""
        return self.fatal is None

    @property
    def findings(self) -> List[Dict[str, Any]]:
        """The findings (severity, message, action, …)."""
        return list(self.data.get("findings", []))

    def raise_if_fatal(self) -> None:
        """Raise ``BadInputError`` with the program's message when a finding
        is fatal."""
        if self.fatal is not None:
            raise BadInputError(self.fatal)

    def __str__(self) -> str:
        return self.table

    def __repr__(self) -> str:
        return f"<robimu.CheckReport: {len(self.findings)} findings, {'ok' if self.ok else 'fatal'}>"


def check(session: Union[Session, PathLike], *, no_excitation: bool = False) -> CheckReport:
    """``robimu check``: the pre-flight check of a recording (a ``Session``
    or a session directory; an unreadable directory is a report with its
    finding, as the program reports it)."""
    if isinstance(session, Session):
        text, table, fatal = _native.check(session._native, no_excitation)
    else:
        text, table, fatal = _native.check_dir(os.fspath(session), no_excitation)
    return CheckReport(json.loads(text), table, fatal)


# -- results ----------------------------------------------------------------


@dataclass(frozen=True)
class Parameter:
    """One estimated parameter (result.json's ``parameters``), SI units."""

    name: str
    value: float
    sigma: float
    """Posterior standard deviation (0 when frozen)."""
    prior: float
    """Prior mean."""
    prior_sigma: float
    unit: str
    frozen: bool


@dataclass(frozen=True)
class Verdict:
    """Whether to trust the calibration (result.json's ``verdict``)."""

    trust: str
    """``good``, ``doubtful`` or ``bad``."""
    reasons: List[str]
    checks: List[Dict[str, Any]]
    """Each check: ``topic``, ``ok``, ``text``."""
    next_steps: List[str]

    def __str__(self) -> str:
        return self.trust


class Result:
    """A calibration result: result.json in memory. ``save`` writes the file
    ``robimu calibrate`` writes (its own writer, to the bit)."""

    def __init__(self, native: Any, text: Optional[str] = None, path: Optional[Path] = None):
        self._native = native
        self._data: Optional[Dict[str, Any]] = None
        self.text = text
        """What ``robimu calibrate`` prints (verdict, summary, parameter
        table), for a calibration computed here."""
        self.path = path
        """The file it was read from or last saved to."""

    @classmethod
    def load(cls, path: PathLike) -> "Result":
        """Read and validate a result file (robimu-result/1 JSON)."""
        p = Path(path)
        return cls(_native.NativeResult.load(os.fspath(p)), path=p)

    def save(self, path: PathLike) -> Path:
        """Write result.json at ``path`` (and, for a calibration computed
        here, its iteration history NAME.convergence.csv next to it, as the
        program does); returns ``path``."""
        p = Path(path)
        self._native.save(os.fspath(p))
        self.path = p
        return p

    def to_json(self) -> str:
        """result.json's text."""
        return self._native.to_json() + "\n"

    def to_dict(self) -> Dict[str, Any]:
        """result.json as a dict."""
        if self._data is None:
            self._data = json.loads(self._native.to_json())
        return self._data

    @property
    def parameters(self) -> Dict[str, Parameter]:
        """Every parameter by name, in result.json's order."""
        return {
            p["name"]: Parameter(
                name=p["name"],
                value=p["value"],
                sigma=p["sigma"],
                prior=p["prior"],
                prior_sigma=p["prior_sigma"],
                unit=p["unit"],
                frozen=p["frozen"],
            )
            for p in self.to_dict()["parameters"]
        }

    @property
    def names(self) -> List[str]:
        """The parameters' names in order."""
        return [p["name"] for p in self.to_dict()["parameters"]]

    @property
    def values(self) -> np.ndarray:
        """The parameters' values in order."""
        return np.array([p["value"] for p in self.to_dict()["parameters"]])

    @property
    def sigmas(self) -> np.ndarray:
        """The parameters' posterior σ in order."""
        return np.array([p["sigma"] for p in self.to_dict()["parameters"]])

    @property
    def covariance(self) -> np.ndarray:
        """The posterior covariance (SI), rows and columns in the order of
        ``covariance_names``."""
        return self._native.covariance()[1]

    @property
    def covariance_names(self) -> List[str]:
        """The covariance's row and column names."""
        return list(self._native.covariance()[0])

    @property
    def verdict(self) -> Optional[Verdict]:
        """The verdict (docs/model.md §8.5)."""
        v = self.to_dict().get("verdict")
        if v is None:
            return None
        return Verdict(
            trust=v["trust"],
            reasons=list(v.get("reasons", [])),
            checks=list(v.get("checks", [])),
            next_steps=list(v.get("next_steps", [])),
        )

    @property
    def effects(self) -> Optional[List[Dict[str, Any]]]:
        """The catalogue effects of the final model (name, spec, parameters,
        evidence)."""
        return self.to_dict().get("effects")

    @property
    def noise_model(self) -> Optional[Dict[str, Any]]:
        """The noise model fitted (white, or AR coefficients per channel) of
        IMU 0 (of each other IMU: ``imu_noise_models``)."""
        return self.to_dict().get("noise_model")

    @property
    def imu_noise_models(self) -> List[Dict[str, Any]]:
        """The noise model of each IMU j ≥ 1 of a several-IMU result
        (``imu``: ``imu<j>``, ``noise_model``); empty for one IMU, whose
        model is ``noise_model``."""
        return list(self.to_dict().get("imu_noise_models", []))

    @property
    def pose_accuracy(self) -> Optional[Dict[str, Any]]:
        """The flange pose accuracy before and after, when it exists."""
        return self.to_dict().get("pose_accuracy")

    @property
    def model_tests(self) -> Optional[Dict[str, Any]]:
        """The tests of the paper's model against the catalogue."""
        return self.to_dict().get("model_tests")

    def table(self, truth: Optional[Union[Session, Mapping[str, float]]] = None) -> str:
        """The parameter table as ``robimu calibrate`` prints it, against the
        truth (a simulated ``Session`` or a dict) when given."""
        if isinstance(truth, Session):
            truth = truth.truth
        values = None if truth is None else [(k, float(v)) for k, v in truth.items()]
        return self._native.table(values)

    def compare(self, truth: Union[Session, Mapping[str, float]]) -> Dict[str, Tuple[float, float, float]]:
        """Each parameter that the truth has: (estimate − truth, σ, z =
        (estimate − truth)/σ)."""
        if isinstance(truth, Session):
            truth = truth.truth or {}
        out = {}
        for name, p in self.parameters.items():
            if name in truth and not p.frozen:
                err = p.value - truth[name]
                out[name] = (err, p.sigma, err / p.sigma if p.sigma > 0 else float("nan"))
        return out

    def __repr__(self) -> str:
        v = self.verdict
        return f"<robimu.Result: {len(self.names)} parameters, verdict {v.trust if v else 'none'}>"


def calibrate(
    session: Union[Session, PathLike],
    *,
    freeze: Union[None, str, Sequence[str]] = None,
    no_prior: bool = False,
    knot_spacing: Optional[float] = None,
    noise: Optional[PathLike] = None,
    model: Optional[str] = None,
    effects: Union[None, str, Sequence[str]] = None,
    resonance_hz: Optional[float] = None,
    resonance_zeta: Optional[float] = None,
    noise_model: Optional[str] = None,
    noise_refits: Optional[int] = None,
    noise_settle: Optional[float] = None,
    imu: Optional[int] = None,
    out: Optional[PathLike] = None,
    progress: Progress = None,
) -> Result:
    """``robimu calibrate``: the MAP calibration of the session (a ``Session``
    or a session directory). The options are the command's flags (``None``:
    the command's default); ``out`` writes result.json there (with its
    convergence log and, with ``effects``, effects.json) as ``--out`` does;
    ``progress`` is a callable given each line the program prints while it
    fits (``True``: print them on stderr). The program's warnings are
    ``RobimuWarning`` warnings."""
    s = _session(session)
    args = _flags(
        freeze=_names(freeze),
        no_prior=no_prior,
        knot_spacing=knot_spacing,
        noise=noise,
        model=model,
        effects=_names(effects),
        resonance_hz=resonance_hz,
        resonance_zeta=resonance_zeta,
        noise_model=noise_model,
        noise_refits=noise_refits,
        noise_settle=noise_settle,
        imu=imu,
    )
    native, warns, text = _native.calibrate(
        s._native,
        args,
        None if out is None else os.fspath(out),
        _progress(progress),
    )
    _warn(warns)
    return Result(native, text=text, path=None if out is None else Path(out))


# -- simulate and plan ------------------------------------------------------


def simulate(
    robot: str = "aubo_i5",
    duration: Optional[float] = None,
    seed: Optional[int] = None,
    *,
    out: Optional[PathLike] = None,
    base: Optional[str] = None,
    tip: Optional[str] = None,
    trajectory: Optional[PathLike] = None,
    rate: Optional[float] = None,
    joint_rate: Optional[float] = None,
    noise_free: bool = False,
    truth: Optional[PathLike] = None,
    tracker: bool = False,
    nominal: Union[None, str, Sequence[str]] = None,
    poses: Optional[int] = None,
    effect: Union[None, str, Sequence[str]] = None,
    bias_walk: Optional[float] = None,
    temperature: Optional[str] = None,
    resonance_hz: Optional[float] = None,
    resonance_zeta: Optional[float] = None,
    noise_model: Optional[str] = None,
    imus: Optional[int] = None,
    imu_position: Any = None,
) -> Session:
    """``robimu simulate``: a simulated session with its truth (truth.toml,
    ``Session.truth``). ``duration`` defaults to 300 s and ``seed`` to 1 as
    in the command; ``out`` keeps the session's directory there (else it is
    written to a temporary directory and removed once read). ``effect`` takes
    ``NAME=MAGNITUDE`` items, ``imu_position`` ``{J: (x, y, z)}``."""
    tmp = None
    if out is None:
        tmp = tempfile.mkdtemp(prefix="robimu-sim-")
        where = Path(tmp) / "session"
    else:
        where = Path(out)
    try:
        args = [f"--robot={robot}"] + _flags(
            base=base,
            tip=tip,
            duration=duration,
            trajectory=trajectory,
            rate=rate,
            joint_rate=joint_rate,
            seed=seed,
            out=where,
            noise_free=noise_free,
            truth=truth,
            tracker=tracker,
            nominal=_names(nominal),
            poses=poses,
            effect=[effect] if isinstance(effect, str) else effect,
            bias_walk=bias_walk,
            temperature=temperature,
            resonance_hz=resonance_hz,
            resonance_zeta=resonance_zeta,
            noise_model=noise_model,
            imus=imus,
            imu_position=_imu_positions(imu_position),
        )
        summary = _native.simulate(args)
        native = _native.NativeSession.load(os.fspath(where))
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    return Session(native, summary=summary, path=None if out is None else where)


@dataclass(frozen=True)
class Plan:
    """A planned excitation trajectory (``robimu plan``'s directory)."""

    path: Path
    """The plan directory (``simulate(trajectory=plan.path)`` follows it)."""
    summary: str
    """What the program prints."""

    def __str__(self) -> str:
        return self.summary


def plan(
    out: PathLike,
    *,
    robot: Optional[str] = None,
    duration: Optional[float] = None,
    knot_spacing: Optional[float] = None,
    block: Optional[int] = None,
    imu_rate: Optional[float] = None,
    rate: Optional[float] = None,
    evaluations: Optional[int] = None,
    seed: Optional[int] = None,
    noise_model: Optional[str] = None,
    imus: Optional[int] = None,
    imu_position: Any = None,
) -> Plan:
    """``robimu plan``: an excitation trajectory planned for identifiability,
    written into the directory ``out``."""
    args = _flags(
        robot=robot,
        duration=duration,
        knot_spacing=knot_spacing,
        block=block,
        imu_rate=imu_rate,
        rate=rate,
        evaluations=evaluations,
        seed=seed,
        noise_model=noise_model,
        imus=imus,
        imu_position=_imu_positions(imu_position),
        out=out,
    )
    return Plan(path=Path(out), summary=_native.plan(args))


# -- diagnose ---------------------------------------------------------------


class Diagnosis:
    """``robimu diagnose``'s finding: the effects the data show, each
    candidate's score (diagnosis.json)."""

    def __init__(self, data: Dict[str, Any], summary: str, path: Optional[Path]):
        self.data = data
        """diagnosis.json as a dict."""
        self.summary = summary
        """What the program prints."""
        self.path = path
        """The diagnosis.json written (``None`` without ``out``)."""

    def __str__(self) -> str:
        return self.summary

    def __repr__(self) -> str:
        return f"<robimu.Diagnosis: {', '.join(sorted(self.data))}>"


def diagnose(
    session: Union[Session, PathLike],
    *,
    out: Optional[PathLike] = None,
    calibration: Optional[PathLike] = None,
    alpha: Optional[float] = None,
    mass_model: Optional[PathLike] = None,
    candidates: Union[None, str, Sequence[str]] = None,
    resonance_hz: Optional[float] = None,
    resonance_zeta: Optional[float] = None,
    noise_model: Optional[str] = None,
    progress: Progress = None,
) -> Diagnosis:
    """``robimu diagnose``: where the calibrated model and the measurements
    disagree, and which catalogue effect explains it. ``out``: write
    diagnosis.json into that directory (the residual figures are the
    command's)."""
    tmp = tempfile.mkdtemp(prefix="robimu-diagnosis-")
    try:
        with _SessionDir(session) as dir:
            where = Path(out) if out is not None else Path(tmp) / "diagnosis"
            args = [os.fspath(dir)] + _flags(
                calibration=calibration,
                out=where,
                alpha=alpha,
                mass_model=mass_model,
                candidates=_names(candidates),
                resonance_hz=resonance_hz,
                resonance_zeta=resonance_zeta,
                noise_model=noise_model,
            )
            text, summary = _native.diagnose(args, _progress(progress))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    path = None if out is None else Path(out) / "diagnosis.json"
    return Diagnosis(json.loads(text), summary, path)


# -- export and robots ------------------------------------------------------

EXPORT_FORMATS = ("urdf", "toml", "kalibr", "correction", "ur-kinematics", "ros2-control")
"""``export``'s formats (``robimu export --format``)."""


def export(
    result: Union[Result, PathLike],
    format: str,
    path: PathLike,
    *,
    robot: Optional[str] = None,
    base: Optional[str] = None,
    tip: Optional[str] = None,
    rate: Optional[float] = None,
    rostopic: Union[None, str, Sequence[str]] = None,
    imu: Optional[int] = None,
    random_walk: Optional[Sequence[float]] = None,
    noise: Optional[PathLike] = None,
) -> List[Path]:
    """``robimu export``: the result (a ``Result`` or a result file) in a
    format other tools read (``EXPORT_FORMATS``), written at ``path``;
    returns the files written. The program's notes are ``RobimuWarning``
    warnings."""
    tmp = None
    try:
        if isinstance(result, Result):
            if result.path is not None and Path(result.path).is_file():
                calibration = Path(result.path)
            else:
                tmp = tempfile.mkdtemp(prefix="robimu-export-")
                calibration = Path(tmp) / "result.json"
                result._native.save(os.fspath(calibration))
        else:
            calibration = Path(result)
        args = _flags(
            calibration=calibration,
            format=format,
            robot=robot,
            base=base,
            tip=tip,
            rate=rate,
            rostopic=_names(rostopic),
            imu=imu,
            random_walk=None if random_walk is None else list(random_walk),
            noise=noise,
            out=path,
        )
        notes, wrote = _native.export(args)
    finally:
        if tmp is not None:
            shutil.rmtree(tmp, ignore_errors=True)
    _warn(notes)
    return [Path(p) for p in wrote]


@dataclass(frozen=True)
class RobotInfo:
    """A built-in robot (``robimu robots``)."""

    name: str
    joints: int
    source: str
    """Where its kinematics come from."""


def robots() -> List[RobotInfo]:
    """The built-in robots (``robimu robots``)."""
    return [RobotInfo(name, joints, source) for name, joints, source in _native.robots()]
