"""Type stubs of the robimu package (python/robimu/__init__.py; the test
python/tests/test_stubs.py checks that they match it)."""

import os

import numpy as np
from ._native import BadInputError as BadInputError, NotConvergedError as NotConvergedError, RobimuError as RobimuError, WriteError as WriteError
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

__all__ = ['BadInputError', 'CheckReport', 'Diagnosis', 'ImuSamples', 'NotConvergedError', 'Parameter', 'Plan', 'Result', 'RobimuError', 'RobimuWarning', 'RobotInfo', 'Session', 'Verdict', 'WriteError', 'calibrate', 'check', 'diagnose', 'export', 'plan', 'robots', 'simulate']

__version__: str

PathLike = str | os.PathLike[str]
Progress = None | bool | Callable[[str], Any]

EXPORT_FORMATS: tuple[str, ...]
"""``export``'s formats (``robimu export --format``)."""

class RobimuWarning(UserWarning):
    """A warning the ``robimu`` program prints as ``warning: …``."""

@dataclass(frozen=True)
class ImuSamples:
    """One IMU's samples (imu.csv or imu<J>.csv)."""
    t: np.ndarray
    accel: np.ndarray
    gyro: np.ndarray
    temp: np.ndarray | None

class Session:
    """A recording (or a simulation) in memory: session.toml, joints.csv,
    imu.csv, …, with the robot it names. The samples are read-only NumPy
    arrays; ``save`` writes the session's files as they were read."""
    summary: str | None
    def __init__(self, native: Any, summary: str | None = None, path: Path | None = None) -> None: ...
    @classmethod
    def load(cls, path: PathLike) -> Session:
        """Read the session directory ``path`` and the robot it names (the
        checks and messages of ``robimu calibrate``'s loading)."""
    def save(self, path: PathLike) -> Path:
        """Write the session's files into the directory ``path`` (created
        when missing); returns it."""
    @property
    def path(self) -> Path | None:
        """The directory the session was read from (``None`` for a
        simulation written to a temporary directory)."""
    @property
    def robot(self) -> str:
        """The robot's name."""
    @property
    def robot_spec(self) -> str:
        """session.toml's ``robot``: a built-in name or a URDF path."""
    @property
    def dof(self) -> int:
        """The robot's joint count."""
    @property
    def n_imus(self) -> int:
        """The number of IMUs (imu.csv, imu1.csv, …)."""
    @property
    def notes(self) -> str | None:
        """session.toml's ``notes``."""
    @property
    def joint_t(self) -> np.ndarray:
        """joints.csv's times, s (n)."""
    @property
    def joints(self) -> np.ndarray:
        """joints.csv's joint angles, rad (n × dof)."""
    @property
    def joint_columns(self) -> list[str]:
        """joints.csv's column names after ``t`` (q1 … qn)."""
    def imu(self, j: int = 0) -> ImuSamples:
        """IMU ``j``'s samples (0: imu.csv, J ≥ 1: imu<J>.csv)."""
    @property
    def tracker(self) -> tuple[np.ndarray, np.ndarray] | None:
        """tracker.csv: times (s) and poses (n × 7: px, py, pz in m, qw, qx,
        qy, qz), when the session has one."""
    @property
    def truth(self) -> dict[str, float] | None:
        """truth.toml's parameters by name (SI), for a simulated session."""


class CheckReport:
    """``robimu check``'s report: each finding with its severity, and the
    fatal findings' error (the program's exit status)."""
    data: dict[str, Any]
    table: str
    fatal: str | None
    def __init__(self, data: dict[str, Any], table: str, fatal: str | None) -> None: ...
    @property
    def ok(self) -> bool:
        """No fatal finding: the session can be calibrated."""
    @property
    def findings(self) -> list[dict[str, Any]]:
        """The findings (severity, message, action, …)."""
    def raise_if_fatal(self) -> None:
        """Raise ``BadInputError`` with the program's message when a finding
        is fatal."""

def check(session: Session | PathLike, *, no_excitation: bool = False) -> CheckReport:
    """``robimu check``: the pre-flight check of a recording (a ``Session``
    or a session directory; an unreadable directory is a report with its
    finding, as the program reports it)."""

@dataclass(frozen=True)
class Parameter:
    """One estimated parameter (result.json's ``parameters``), SI units."""
    name: str
    value: float
    sigma: float
    prior: float
    prior_sigma: float
    unit: str
    frozen: bool

@dataclass(frozen=True)
class Verdict:
    """Whether to trust the calibration (result.json's ``verdict``)."""
    trust: str
    reasons: list[str]
    checks: list[dict[str, Any]]
    next_steps: list[str]

class Result:
    """A calibration result: result.json in memory. ``save`` writes the file
    ``robimu calibrate`` writes (its own writer, to the bit)."""
    text: str | None
    path: Path | None
    def __init__(self, native: Any, text: str | None = None, path: Path | None = None) -> None: ...
    @classmethod
    def load(cls, path: PathLike) -> Result:
        """Read and validate a result file (robimu-result/1 JSON)."""
    def save(self, path: PathLike) -> Path:
        """Write result.json at ``path`` (and, for a calibration computed
        here, its iteration history NAME.convergence.csv next to it, as the
        program does); returns ``path``."""
    def to_json(self) -> str:
        """result.json's text."""
    def to_dict(self) -> dict[str, Any]:
        """result.json as a dict."""
    @property
    def parameters(self) -> dict[str, Parameter]:
        """Every parameter by name, in result.json's order."""
    @property
    def names(self) -> list[str]:
        """The parameters' names in order."""
    @property
    def values(self) -> np.ndarray:
        """The parameters' values in order."""
    @property
    def sigmas(self) -> np.ndarray:
        """The parameters' posterior σ in order."""
    @property
    def covariance(self) -> np.ndarray:
        """The posterior covariance (SI), rows and columns in the order of
        ``covariance_names``."""
    @property
    def covariance_names(self) -> list[str]:
        """The covariance's row and column names."""
    @property
    def verdict(self) -> Verdict | None:
        """The verdict (docs/model.md §8.5)."""
    @property
    def effects(self) -> list[dict[str, Any]] | None:
        """The catalogue effects of the final model (name, spec, parameters,
        evidence)."""
    @property
    def noise_model(self) -> dict[str, Any] | None:
        """The noise model fitted (white, or AR coefficients per channel) of
        IMU 0 (of each other IMU: ``imu_noise_models``)."""
    @property
    def imu_noise_models(self) -> list[dict[str, Any]]:
        """The noise model of each IMU j ≥ 1 of a several-IMU result
        (``imu``: ``imu<j>``, ``noise_model``); empty for one IMU, whose
        model is ``noise_model``."""
    @property
    def pose_accuracy(self) -> dict[str, Any] | None:
        """The flange pose accuracy before and after, when it exists."""
    @property
    def model_tests(self) -> dict[str, Any] | None:
        """The tests of the paper's model against the catalogue."""
    def table(self, truth: Session | Mapping[str, float] | None = None) -> str:
        """The parameter table as ``robimu calibrate`` prints it, against the
        truth (a simulated ``Session`` or a dict) when given."""
    def compare(self, truth: Session | Mapping[str, float]) -> dict[str, tuple[float, float, float]]:
        """Each parameter that the truth has: (estimate − truth, σ, z =
        (estimate − truth)/σ)."""

def calibrate(session: Session | PathLike, *, freeze: None | str | Sequence[str] = None, no_prior: bool = False, knot_spacing: float | None = None, noise: PathLike | None = None, model: str | None = None, effects: None | str | Sequence[str] = None, resonance_hz: float | None = None, resonance_zeta: float | None = None, noise_model: str | None = None, noise_refits: int | None = None, noise_settle: float | None = None, imu: int | None = None, out: PathLike | None = None, progress: Progress = None) -> Result:
    """``robimu calibrate``: the MAP calibration of the session (a ``Session``
    or a session directory). The options are the command's flags (``None``:
    the command's default); ``out`` writes result.json there (with its
    convergence log and, with ``effects``, effects.json) as ``--out`` does;
    ``progress`` is a callable given each line the program prints while it
    fits (``True``: print them on stderr). The program's warnings are
    ``RobimuWarning`` warnings."""
def simulate(robot: str = 'aubo_i5', duration: float | None = None, seed: int | None = None, *, out: PathLike | None = None, base: str | None = None, tip: str | None = None, trajectory: PathLike | None = None, rate: float | None = None, joint_rate: float | None = None, noise_free: bool = False, truth: PathLike | None = None, tracker: bool = False, nominal: None | str | Sequence[str] = None, poses: int | None = None, effect: None | str | Sequence[str] = None, bias_walk: float | None = None, temperature: str | None = None, resonance_hz: float | None = None, resonance_zeta: float | None = None, noise_model: str | None = None, imus: int | None = None, imu_position: Any = None) -> Session:
    """``robimu simulate``: a simulated session with its truth (truth.toml,
    ``Session.truth``). ``duration`` defaults to 300 s and ``seed`` to 1 as
    in the command; ``out`` keeps the session's directory there (else it is
    written to a temporary directory and removed once read). ``effect`` takes
    ``NAME=MAGNITUDE`` items, ``imu_position`` ``{J: (x, y, z)}``."""

@dataclass(frozen=True)
class Plan:
    """A planned excitation trajectory (``robimu plan``'s directory)."""
    path: Path
    summary: str

def plan(out: PathLike, *, robot: str | None = None, duration: float | None = None, knot_spacing: float | None = None, block: int | None = None, imu_rate: float | None = None, rate: float | None = None, evaluations: int | None = None, seed: int | None = None, noise_model: str | None = None, imus: int | None = None, imu_position: Any = None) -> Plan:
    """``robimu plan``: an excitation trajectory planned for identifiability,
    written into the directory ``out``."""

class Diagnosis:
    """``robimu diagnose``'s finding: the effects the data show, each
    candidate's score (diagnosis.json)."""
    data: dict[str, Any]
    summary: str
    path: Path | None
    def __init__(self, data: dict[str, Any], summary: str, path: Path | None) -> None: ...

def diagnose(session: Session | PathLike, *, out: PathLike | None = None, calibration: PathLike | None = None, alpha: float | None = None, mass_model: PathLike | None = None, candidates: None | str | Sequence[str] = None, resonance_hz: float | None = None, resonance_zeta: float | None = None, noise_model: str | None = None, progress: Progress = None) -> Diagnosis:
    """``robimu diagnose``: where the calibrated model and the measurements
    disagree, and which catalogue effect explains it. ``out``: write
    diagnosis.json into that directory (the residual figures are the
    command's)."""
def export(result: Result | PathLike, format: str, path: PathLike, *, robot: str | None = None, base: str | None = None, tip: str | None = None, rate: float | None = None, rostopic: None | str | Sequence[str] = None, imu: int | None = None, random_walk: Sequence[float] | None = None, noise: PathLike | None = None) -> list[Path]:
    """``robimu export``: the result (a ``Result`` or a result file) in a
    format other tools read (``EXPORT_FORMATS``), written at ``path``;
    returns the files written. The program's notes are ``RobimuWarning``
    warnings."""

@dataclass(frozen=True)
class RobotInfo:
    """A built-in robot (``robimu robots``)."""
    name: str
    joints: int
    source: str

def robots() -> list[RobotInfo]:
    """The built-in robots (``robimu robots``)."""
