"""Type stubs of robimu's compiled extension (python/src/lib.rs): the
program's pipelines over its own flag parsers. The package (robimu/__init__.py)
is the API; this module is its engine. python/tests/test_stubs.py checks
that these signatures match the extension's."""

from typing import Any, Callable, Optional

import numpy as np

__version__: str

class RobimuError(Exception):
    """Any error of robimu; the message is the program's."""

class BadInputError(RobimuError):
    """The input cannot be used (a file, a flag, a session's content)."""

class NotConvergedError(RobimuError):
    """The estimation failed (did not converge, a singular system)."""

class WriteError(RobimuError):
    """A file could not be written."""

class NativeSession:
    """A session in memory (`Session.load`, `simulate`), with its robot and
    the files it was read from (written again by `save`)."""

    @staticmethod
    def load(dir: str) -> NativeSession:
        """The session in `dir` with the robot it names (`robimu calibrate`'s
        loading: the same checks, the same messages)."""
    def save(self, dir: str) -> None:
        """Writes the session's files into `dir` (created when missing)."""
    def joints(self) -> tuple[np.ndarray, np.ndarray]:
        """joints.csv: times (s) and joint angles (rad), n × dof."""
    def imu(self, j: int) -> tuple[np.ndarray, np.ndarray, Optional[np.ndarray]]:
        """IMU j's file: times (s), samples n × 6 (ax, ay, az in m/s², gx, gy,
        gz in rad/s) and the temperature column (°C) when it has one."""
    def tracker(self) -> Optional[tuple[np.ndarray, np.ndarray]]:
        """tracker.csv: times (s) and poses n × 7 (px, py, pz in m, qw, qx, qy,
        qz), when the session has one."""
    def truth(self) -> Optional[list[tuple[str, float]]]:
        """truth.toml's parameters (name, value in SI), when the session has one."""
    @property
    def path(self) -> str:
        """The directory the session was read from."""
    @property
    def robot_spec(self) -> str:
        """session.toml's `robot`."""
    @property
    def robot(self) -> str:
        """The robot's name."""
    @property
    def dof(self) -> int:
        """The robot's joint count."""
    @property
    def n_imus(self) -> int:
        """The number of IMUs."""
    @property
    def notes(self) -> Optional[str]:
        """session.toml's `notes`."""
    @property
    def joint_columns(self) -> list[str]:
        """joints.csv's columns after `t`."""

class NativeResult:
    """A calibration result: result.json's record, with the calibration's
    iteration history when it was computed here."""

    @staticmethod
    def load(path: str) -> NativeResult:
        """Reads and validates a result file."""
    def save(self, path: str) -> Optional[str]:
        """Writes the result file (the CLI's writer) and, for a calibration
        computed here, its iteration history next to it; returns the
        history's path."""
    def to_json(self) -> str:
        """result.json's text (without the final newline)."""
    def covariance(self) -> tuple[list[str], np.ndarray]:
        """The covariance's parameter names and matrix."""
    def table(self, truth: Optional[list[tuple[str, float]]] = None) -> str:
        """The parameter table as `robimu calibrate` prints it, against
        `truth` (name, value) when given."""

def calibrate(
    session: NativeSession,
    args: list[str],
    out: Optional[str] = None,
    progress: Optional[Callable[[str], Any]] = None,
) -> tuple[NativeResult, list[str], str]:
    """`robimu calibrate SESSION FLAGS…` on a session in memory: the result,
    the warnings the program prints, and the text it prints above the
    parameter table. `args`: the flags after the session (as the program
    takes them); `out`: write result.json there (with its convergence log
    and effects.json, as the program does)."""

def bench_rust_calibrate(session: NativeSession) -> float:
    """The in-memory Rust call that `calibrate` wraps, timed (the benchmark's
    reference, python/bench/): `Prepared::new` and `fit` with the default
    settings on this thread, the GIL released; returns the seconds."""

def check(session: NativeSession, no_excitation: bool) -> tuple[str, str, Optional[str]]:
    """`robimu check` on a session in memory: the report's JSON (`--json`),
    the table the program prints and the fatal findings' error, if any."""

def check_dir(dir: str, no_excitation: bool) -> tuple[str, str, Optional[str]]:
    """`robimu check DIR` of a directory (an unreadable session is a report
    with its finding, as the program reports it)."""

def simulate(args: list[str]) -> str:
    """`robimu simulate FLAGS…`: writes the session (`--out` among the
    flags); returns what the program prints."""

def plan(args: list[str]) -> str:
    """`robimu plan FLAGS…`: writes the plan (`--out` among the flags) and
    returns what the program prints."""

def diagnose(args: list[str], progress: Optional[Callable[[str], Any]] = None) -> tuple[str, str]:
    """`robimu diagnose SESSION FLAGS…` without the figures: diagnosis.json's
    text (also written into the output directory) and the summary the
    program prints."""

def export(args: list[str]) -> tuple[list[str], list[str]]:
    """`robimu export FLAGS…`: the notes and the files written."""

def robots() -> list[tuple[str, int, str]]:
    """The built-in robots: name, joint count, source."""

def run_cli(args: list[str]) -> int:
    """`robimu ARGS…` in this process (`args[0]` is the program's name);
    returns the exit code."""
