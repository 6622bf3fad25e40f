//! `robimu._native`: the Rust side of the Python package (PyO3, stable
//! ABI). The package's own modules (`python/robimu/`) give it its Python
//! shape; this module calls the same library functions as the `robimu`
//! program, with its flags parsed by the program's own parsers, so that a
//! call writes the same files as the command.
//!
//! Long calls run on a worker thread while the calling thread waits with
//! the GIL released, checking for Ctrl-C (`KeyboardInterrupt`) and passing
//! the progress lines to a Python callable.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::time::{Duration, Instant};

use numpy::{PyArray1, PyArray2, PyArrayMethods};
use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;

use robimu_cli::{CalibrateCmd, CalibrateFlags, DiagnoseCmd, ExportCmd, PlanCmd, SimulateCmd};
use robimu_model::{Robot, BUILTIN_ROBOTS};
use robimu_report::diagnosis::DiagnosisSummary;
use robimu_report::fit_summary::WeakDirectionsWarning;
use robimu_report::ParameterTable;
use robimu_session::result::CalibrationResult;
use robimu_session::{Session, Table, Truth};
use robimu_solver::IterationRecord;
use robimu_workflows::calibrate::Calibration;
use robimu_workflows::check::{check_session, CheckOptions, CheckReport};
use robimu_workflows::export::Notice;
use robimu_workflows::pipeline::{fatal_findings, write_result};
use robimu_workflows::{
    diagnose_session, is_urdf, load_session, FitEvent, PipelineError, Prepared,
};

create_exception!(
    robimu,
    RobimuError,
    PyException,
    "Every error robimu raises; its text is the `robimu` program's message."
);
create_exception!(
    robimu,
    BadInputError,
    RobimuError,
    "The input cannot be used: a session, a file it names, an option."
);
create_exception!(
    robimu,
    NotConvergedError,
    RobimuError,
    "The estimation failed: it did not converge, or the problem is singular."
);
create_exception!(
    robimu,
    WriteError,
    RobimuError,
    "A file could not be written."
);

/// The program's message of `e`: its text and one `  caused by: …` line
/// per cause (without the program's `error: `).
fn message(e: &anyhow::Error) -> String {
    let text = robimu_cli::error_report(e);
    text.strip_prefix("error: ")
        .unwrap_or(&text)
        .trim_end()
        .to_string()
}

/// An input error (`BadInputError`) with the program's message.
fn bad_input(e: impl Into<anyhow::Error>) -> PyErr {
    BadInputError::new_err(message(&e.into()))
}

/// A pipeline's error as the exception of its kind.
fn pipeline(e: PipelineError) -> PyErr {
    let kind = match &e {
        PipelineError::Input(_) => 0,
        PipelineError::Fit(_) => 1,
        PipelineError::Write(_) => 2,
    };
    let text = message(&anyhow::Error::from(e));
    match kind {
        0 => BadInputError::new_err(text),
        1 => NotConvergedError::new_err(text),
        _ => WriteError::new_err(text),
    }
}

/// A file that cannot be written, as `WriteError`.
fn write_error(e: impl Into<anyhow::Error>) -> PyErr {
    WriteError::new_err(message(&e.into()))
}

/// A command's flags parsed as the program parses them (`args`: the flags
/// and positional arguments after the command's name); a usage error is a
/// `BadInputError` with clap's message.
fn parse<T: clap::Args + clap::FromArgMatches>(
    name: &'static str,
    args: Vec<String>,
) -> PyResult<T> {
    let usage = |e: clap::Error| {
        let text = e.render().to_string();
        let text = text.strip_prefix("error: ").unwrap_or(&text);
        let text = text.split("\n\nUsage:").next().unwrap_or(text);
        BadInputError::new_err(format!("robimu {name}: {}", text.trim_end()))
    };
    let cmd = T::augment_args(clap::Command::new(name).no_binary_name(true));
    let matches = cmd.try_get_matches_from(args).map_err(usage)?;
    T::from_arg_matches(&matches).map_err(usage)
}

/// What a worker thread sends the waiting caller.
enum Msg<T> {
    Line(String),
    Done(T),
}

/// Runs `work` on a worker thread while the caller waits with the GIL
/// released: each line `work` reports goes to `progress`, and Ctrl-C (any
/// signal handler's exception) ends the wait with `KeyboardInterrupt`
/// (the worker then finishes in the background, its result dropped).
fn run_detached<T: Send + 'static>(
    py: Python<'_>,
    progress: Option<&Bound<'_, PyAny>>,
    work: impl FnOnce(&dyn Fn(String)) -> PyResult<T> + Send + 'static,
) -> PyResult<T> {
    let (tx, mut rx) = mpsc::channel::<Msg<PyResult<T>>>();
    let lines = tx.clone();
    std::thread::Builder::new()
        .name("robimu".into())
        .spawn(move || {
            let line = |s: String| {
                let _ = lines.send(Msg::Line(s));
            };
            let out = work(&line);
            let _ = tx.send(Msg::Done(out));
        })
        .map_err(|e| RobimuError::new_err(format!("cannot start a worker thread: {e}")))?;
    loop {
        let (msg, back) = py.detach(move || (rx.recv_timeout(Duration::from_millis(50)), rx));
        rx = back;
        match msg {
            Ok(Msg::Done(out)) => return out,
            Ok(Msg::Line(s)) => {
                if let Some(f) = progress {
                    f.call1((s,))?;
                }
            }
            Err(RecvTimeoutError::Timeout) => {}
            Err(RecvTimeoutError::Disconnected) => {
                return Err(RobimuError::new_err(
                    "the calculation stopped without a result (its thread panicked; see stderr)",
                ))
            }
        }
        py.check_signals()?;
    }
}

/// A session in memory (`Session.load`, `simulate`), with its robot and
/// the files it was read from (written again by `save`).
#[pyclass(module = "robimu._native", frozen)]
pub struct NativeSession {
    session: Session,
    robot: Robot,
    files: Vec<(String, Vec<u8>)>,
}

/// A table's times (n) and values (n × width) as NumPy arrays.
type TableArrays<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray2<f64>>);

/// A table's times and its values as an n × width array.
fn table_arrays<'py>(py: Python<'py>, t: &Table) -> PyResult<TableArrays<'py>> {
    let times = PyArray1::from_slice(py, &t.t);
    let values = PyArray1::from_slice(py, &t.values).reshape([t.len(), t.width()])?;
    Ok((times, values))
}

/// The files of the session in `dir` that `save` writes again: session.toml,
/// joints.csv, each IMU's file, tracker.csv and truth.toml when present,
/// and the URDF that session.toml names by a relative path.
fn session_files(dir: &Path, s: &Session) -> anyhow::Result<Vec<(String, Vec<u8>)>> {
    use robimu_session::files;
    let mut names: Vec<String> = vec![files::META.into(), files::JOINTS.into()];
    names.extend((0..s.n_imus()).map(files::imu_csv));
    for optional in [files::TRACKER, files::TRUTH] {
        if dir.join(optional).is_file() {
            names.push(optional.into());
        }
    }
    let robot = Path::new(&s.meta.robot);
    if is_urdf(robot) && robot.is_relative() && dir.join(robot).is_file() {
        names.push(s.meta.robot.clone());
    }
    names
        .into_iter()
        .map(|name| {
            let path = dir.join(&name);
            let bytes = std::fs::read(&path)
                .map_err(|e| anyhow::anyhow!("cannot read {}: {e}", path.display()))?;
            Ok((name, bytes))
        })
        .collect()
}

#[pymethods]
impl NativeSession {
    /// The session in `dir` with the robot it names (`robimu calibrate`'s
    /// loading: the same checks, the same messages).
    #[staticmethod]
    fn load(py: Python<'_>, dir: PathBuf) -> PyResult<Self> {
        py.detach(move || {
            let (session, robot) = load_session(&dir).map_err(bad_input)?;
            let files = session_files(&dir, &session).map_err(bad_input)?;
            Ok(Self {
                session,
                robot,
                files,
            })
        })
    }

    /// Writes the session's files into `dir` (created when missing).
    fn save(&self, py: Python<'_>, dir: PathBuf) -> PyResult<()> {
        py.detach(|| {
            std::fs::create_dir_all(&dir).map_err(|e| {
                write_error(anyhow::anyhow!(
                    "cannot create the session directory {}: {e}",
                    dir.display()
                ))
            })?;
            for (name, bytes) in &self.files {
                let path = dir.join(name);
                if let Some(parent) = path.parent() {
                    std::fs::create_dir_all(parent).map_err(|e| {
                        write_error(anyhow::anyhow!("cannot create {}: {e}", parent.display()))
                    })?;
                }
                std::fs::write(&path, bytes).map_err(|e| {
                    write_error(anyhow::anyhow!("cannot write {}: {e}", path.display()))
                })?;
            }
            Ok(())
        })
    }

    /// The directory the session was read from.
    #[getter]
    fn path(&self) -> PathBuf {
        self.session.dir.clone()
    }

    /// session.toml's `robot` (a built-in name or a URDF path).
    #[getter]
    fn robot_spec(&self) -> String {
        self.session.meta.robot.clone()
    }

    /// The robot's name.
    #[getter]
    fn robot(&self) -> String {
        self.robot.name().to_string()
    }

    /// The robot's joint count.
    #[getter]
    fn dof(&self) -> usize {
        self.robot.dof()
    }

    /// The number of IMUs.
    #[getter]
    fn n_imus(&self) -> usize {
        self.session.n_imus()
    }

    /// session.toml's `notes`.
    #[getter]
    fn notes(&self) -> Option<String> {
        self.session.meta.notes.clone()
    }

    /// joints.csv's column names after `t`.
    #[getter]
    fn joint_columns(&self) -> Vec<String> {
        self.session.joints.columns.clone()
    }

    /// joints.csv: times (s) and joint angles (rad), n × dof.
    fn joints<'py>(&self, py: Python<'py>) -> PyResult<TableArrays<'py>> {
        table_arrays(py, &self.session.joints)
    }

    /// IMU j's file: times (s), samples n × 6 (ax, ay, az in m/s², gx, gy,
    /// gz in rad/s) and the temperature column (°C) when it has one.
    #[allow(clippy::type_complexity)]
    fn imu<'py>(
        &self,
        py: Python<'py>,
        j: usize,
    ) -> PyResult<(
        Bound<'py, PyArray1<f64>>,
        Bound<'py, PyArray2<f64>>,
        Option<Bound<'py, PyArray1<f64>>>,
    )> {
        let (table, temp) = match j {
            0 => (&self.session.imu, self.session.imu_temp.as_ref()),
            j => match self.session.extra_imus.get(j - 1) {
                Some(t) => (&t.samples, t.temp.as_ref()),
                None => {
                    return Err(BadInputError::new_err(format!(
                        "IMU {j}: the session has {} IMU{} (0..{})",
                        self.session.n_imus(),
                        if self.session.n_imus() == 1 { "" } else { "s" },
                        self.session.n_imus() - 1
                    )))
                }
            },
        };
        let (t, z) = table_arrays(py, table)?;
        Ok((t, z, temp.map(|v| PyArray1::from_slice(py, v))))
    }

    /// tracker.csv: times (s) and poses n × 7 (px, py, pz in m, qw, qx, qy,
    /// qz), when the session has one.
    fn tracker<'py>(&self, py: Python<'py>) -> PyResult<Option<TableArrays<'py>>> {
        self.session
            .tracker
            .as_ref()
            .map(|t| table_arrays(py, t))
            .transpose()
    }

    /// truth.toml's parameters (name, value in SI), when the session has one.
    fn truth(&self) -> Option<Vec<(String, f64)>> {
        self.session.truth.as_ref().map(|t| t.values.clone())
    }
}

/// A calibration result: result.json's record, with the calibration's
/// iteration history when it was computed here.
#[pyclass(module = "robimu._native", frozen)]
pub struct NativeResult {
    result: CalibrationResult,
    cal: Option<Calibration>,
}

#[pymethods]
impl NativeResult {
    /// Reads and validates a result file.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        let result = CalibrationResult::read(&path).map_err(bad_input)?;
        Ok(Self { result, cal: None })
    }

    /// Writes the result file (the CLI's writer) and, for a calibration
    /// computed here, its iteration history next to it; returns the
    /// history's path.
    fn save(&self, path: PathBuf) -> PyResult<Option<PathBuf>> {
        match &self.cal {
            Some(cal) => Ok(Some(
                write_result(&self.result, cal, &path).map_err(pipeline)?,
            )),
            None => {
                self.result.write(&path).map_err(write_error)?;
                Ok(None)
            }
        }
    }

    /// result.json's text (without the final newline).
    fn to_json(&self) -> PyResult<String> {
        self.result.to_json().map_err(RobimuError::new_err)
    }

    /// The covariance's parameter names and matrix.
    fn covariance<'py>(
        &self,
        py: Python<'py>,
    ) -> PyResult<(Vec<String>, Bound<'py, PyArray2<f64>>)> {
        let c = &self.result.covariance;
        let n = c.names.len();
        let flat: Vec<f64> = c.matrix.iter().flatten().copied().collect();
        if flat.len() != n * n {
            return Err(RobimuError::new_err(format!(
                "the covariance is not {n} × {n} ({} values)",
                flat.len()
            )));
        }
        Ok((
            c.names.clone(),
            PyArray1::from_vec(py, flat).reshape([n, n])?,
        ))
    }

    /// The parameter table as `robimu calibrate` prints it, against
    /// `truth` (name, value) when given.
    #[pyo3(signature = (truth=None))]
    fn table(&self, truth: Option<Vec<(String, f64)>>) -> String {
        let truth = truth.map(|values| Truth { values });
        ParameterTable::new(&self.result, truth.as_ref()).to_string()
    }
}

/// `robimu calibrate SESSION FLAGS…` on a session in memory: the result,
/// the warnings the program prints, and the text it prints above the
/// parameter table. `args`: the flags after the session (as the program
/// takes them); `out`: write result.json there (with its convergence log
/// and effects.json, as the program does).
#[pyfunction]
#[pyo3(signature = (session, args, out=None, progress=None))]
fn calibrate(
    py: Python<'_>,
    session: &NativeSession,
    args: Vec<String>,
    out: Option<PathBuf>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<(NativeResult, Vec<String>, String)> {
    let mut argv = vec![session.session.dir.display().to_string()];
    argv.extend(args);
    let cmd: CalibrateCmd = parse("calibrate", argv)?;
    let flags: CalibrateFlags = cmd.fit;
    let file = flags.noise_file().map_err(bad_input)?;
    let path = out
        .as_deref()
        .map(|o| robimu_cli::output_path(Some(o), o.to_path_buf()))
        .transpose()
        .map_err(bad_input)?;
    let settings = flags.settings().map_err(bad_input)?;
    let knot_chosen = flags.knot_spacing.is_none();
    let (s, robot) = (session.session.clone(), session.robot.clone());
    run_detached(py, progress.as_ref(), move |line| {
        let mut warnings = Vec::new();
        let p = Prepared::new(s, robot, &settings, file.as_ref(), |w| warnings.push(w))
            .map_err(pipeline)?;
        line(IterationRecord::HEADER.to_string());
        let fitted = p
            .fit(|e| match e {
                FitEvent::Iteration(r) => line(r.to_string()),
                FitEvent::Stage(s) => line(format!("-- {s}")),
            })
            .map_err(pipeline)?;
        let text = format!(
            "{}\n{}",
            robimu_cli::fit_summary(&p, &fitted, knot_chosen),
            ParameterTable::new(&fitted.result, p.session.truth.as_ref())
        );
        warnings.extend(fitted.noise.warning.clone());
        let weak = WeakDirectionsWarning::new(&fitted.cal.weak_directions, &p.layout).to_string();
        let weak = weak.trim();
        if !weak.is_empty() {
            warnings.push(weak.strip_prefix("warning: ").unwrap_or(weak).to_string());
        }
        if let Some(path) = &path {
            fitted.write(path).map_err(pipeline)?;
            p.write_effects(&fitted, path).map_err(pipeline)?;
        }
        let result = NativeResult {
            result: fitted.result,
            cal: Some(fitted.cal),
        };
        Ok((result, warnings, text))
    })
}

/// The in-memory Rust call that `calibrate` wraps, timed (the benchmark's
/// reference, python/bench/): `Prepared::new` and `fit` with the default
/// settings on this thread, the GIL released; returns the seconds.
#[pyfunction]
fn bench_rust_calibrate(py: Python<'_>, session: &NativeSession) -> PyResult<f64> {
    let (s, robot) = (session.session.clone(), session.robot.clone());
    py.detach(move || {
        let start = Instant::now();
        let settings = CalibrateFlags::default().settings().map_err(bad_input)?;
        let p = Prepared::new(s, robot, &settings, None, |_| {}).map_err(pipeline)?;
        let fitted = p.fit(|_| {}).map_err(pipeline)?;
        let seconds = start.elapsed().as_secs_f64();
        drop(fitted);
        Ok(seconds)
    })
}

/// `robimu check` on a session in memory: the report's JSON (`--json`),
/// the table the program prints and the fatal findings' error, if any.
#[pyfunction]
fn check(
    py: Python<'_>,
    session: &NativeSession,
    no_excitation: bool,
) -> PyResult<(String, String, Option<String>)> {
    py.detach(|| {
        let opts = CheckOptions {
            excitation: !no_excitation,
        };
        let report = check_session(&session.session, &session.robot, &opts);
        check_outcome(&report, &session.session.dir)
    })
}

/// `robimu check DIR` of a directory (an unreadable session is a report
/// with its finding, as the program reports it).
#[pyfunction]
fn check_dir(
    py: Python<'_>,
    dir: PathBuf,
    no_excitation: bool,
) -> PyResult<(String, String, Option<String>)> {
    py.detach(|| {
        let opts = CheckOptions {
            excitation: !no_excitation,
        };
        let report = robimu_cli::check_dir(&dir, &opts).map_err(bad_input)?;
        check_outcome(&report, &dir)
    })
}

fn check_outcome(report: &CheckReport, dir: &Path) -> PyResult<(String, String, Option<String>)> {
    let json =
        serde_json::to_string_pretty(report).map_err(|e| RobimuError::new_err(e.to_string()))?;
    let table = robimu_report::check::CheckTable {
        report,
        min: robimu_workflows::check::Severity::Info,
    }
    .to_string();
    let fatal = fatal_findings(report, dir).err().map(|e| message(&e));
    Ok((json, table, fatal))
}

/// `robimu simulate FLAGS…`: writes the session (`--out` among the flags)
/// and returns what the program prints.
#[pyfunction]
fn simulate(py: Python<'_>, args: Vec<String>) -> PyResult<String> {
    let cmd: SimulateCmd = parse("simulate", args)?;
    run_detached(py, None, move |_| {
        Ok(cmd.simulate().map_err(bad_input)?.to_string())
    })
}

/// `robimu plan FLAGS…`: writes the plan (`--out` among the flags) and
/// returns the summary the program prints.
#[pyfunction]
fn plan(py: Python<'_>, args: Vec<String>) -> PyResult<String> {
    let cmd: PlanCmd = parse("plan", args)?;
    run_detached(py, None, move |_| cmd.plan().map_err(bad_input))
}

/// `robimu diagnose SESSION FLAGS…` without the figures: diagnosis.json's
/// text (also written into the output directory) and the summary the
/// program prints.
#[pyfunction]
#[pyo3(signature = (args, progress=None))]
fn diagnose(
    py: Python<'_>,
    args: Vec<String>,
    progress: Option<Bound<'_, PyAny>>,
) -> PyResult<(String, String)> {
    let cmd: DiagnoseCmd = parse("diagnose", args)?;
    let settings = cmd.settings();
    run_detached(py, progress.as_ref(), move |line| {
        let d =
            diagnose_session(&cmd.session, &settings, |m| line(m.to_string())).map_err(pipeline)?;
        d.write_json(&settings.out).map_err(pipeline)?;
        let json = serde_json::to_string_pretty(&d.diagnosis.to_json(&d.layout))
            .map_err(|e| RobimuError::new_err(e.to_string()))?;
        Ok((json, DiagnosisSummary(&d.diagnosis).to_string()))
    })
}

/// `robimu export FLAGS…`: the notes and the files written.
#[pyfunction]
fn export(py: Python<'_>, args: Vec<String>) -> PyResult<(Vec<String>, Vec<PathBuf>)> {
    let cmd: ExportCmd = parse("export", args)?;
    py.detach(move || {
        let (mut notes, mut wrote) = (Vec::new(), Vec::new());
        cmd.export(&mut |n| match n {
            Notice::Note(text) => notes.push(text),
            Notice::Wrote(path) => wrote.push(path),
        })
        .map_err(bad_input)?;
        Ok((notes, wrote))
    })
}

/// The built-in robots: name, joint count, source (`robimu robots`).
#[pyfunction]
fn robots() -> PyResult<Vec<(String, usize, String)>> {
    BUILTIN_ROBOTS
        .iter()
        .map(|name| {
            let r = Robot::builtin(name).ok_or_else(|| {
                RobimuError::new_err(format!("the built-in robot `{name}` is missing"))
            })?;
            let source = r
                .description()
                .source
                .clone()
                .unwrap_or_else(|| "docs/model.md §6 (the paper's AUBO i5, §8)".into());
            Ok((name.to_string(), r.dof(), source))
        })
        .collect()
}

/// `robimu ARGS…` in this process (`args[0]` is the program's name);
/// returns the exit code.
#[pyfunction]
fn run_cli(py: Python<'_>, args: Vec<String>) -> u8 {
    py.detach(move || robimu_cli::run(args))
}

/// The extension module.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // the program's allocator settings (fewer page faults in a calibration)
    robimu_cli::keep_freed_memory();
    let py = m.py();
    m.add("RobimuError", py.get_type::<RobimuError>())?;
    m.add("BadInputError", py.get_type::<BadInputError>())?;
    m.add("NotConvergedError", py.get_type::<NotConvergedError>())?;
    m.add("WriteError", py.get_type::<WriteError>())?;
    m.add_class::<NativeSession>()?;
    m.add_class::<NativeResult>()?;
    m.add_function(wrap_pyfunction!(calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(bench_rust_calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(check, m)?)?;
    m.add_function(wrap_pyfunction!(check_dir, m)?)?;
    m.add_function(wrap_pyfunction!(simulate, m)?)?;
    m.add_function(wrap_pyfunction!(plan, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(export, m)?)?;
    m.add_function(wrap_pyfunction!(robots, m)?)?;
    m.add_function(wrap_pyfunction!(run_cli, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
