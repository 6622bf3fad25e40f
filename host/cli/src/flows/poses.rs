//! `robimu calibrate` of a session with tool poses (docs/model.md §7.9):
//! the library's [`calibrate_pose_session`] with a progress line, the
//! verdict, a summary of the fit, the parameter table and the result file.

use std::io::Write;
use std::path::Path;

use anyhow::bail;
use robimu_report::verdict::VerdictText;
use robimu_report::ParameterTable;
use robimu_solver::IterationRecord;
use robimu_workflows::pipeline::poses::{
    calibrate_pose_session, load_pose_session, pose_options, PoseFitted,
};
use robimu_workflows::FitEvent;

use crate::args::CalibrateFlags;
use crate::input::{output_path, Progress};

/// The flags of `robimu calibrate` that a pose session does not take,
/// given with other than their defaults (`--knot-spacing` and `--report`
/// it takes).
pub fn joint_only_flags(flags: &CalibrateFlags, windows: bool) -> Vec<&'static str> {
    let d = CalibrateFlags::default();
    [
        (windows, "--windows"),
        (!flags.freeze.is_empty(), "--freeze"),
        (flags.no_prior, "--no-prior"),
        (flags.noise.is_some(), "--noise"),
        (flags.model != d.model, "--model"),
        (!flags.effects.is_empty(), "--effects"),
        (
            flags.resonance.resonance_hz != d.resonance.resonance_hz
                || flags.resonance.resonance_zeta != d.resonance.resonance_zeta,
            "--resonance-hz/--resonance-zeta",
        ),
        (flags.noise_model != d.noise_model, "--noise-model"),
        (flags.noise_refits != d.noise_refits, "--noise-refits"),
        (flags.noise_settle.is_some(), "--noise-settle"),
        (flags.imu.is_some(), "--imu"),
    ]
    .into_iter()
    .filter_map(|(given, name)| given.then_some(name))
    .collect()
}

/// Calibrate the pose session in `dir`, print the verdict and the table,
/// write the result file (`out`, default result.json in `dir`), its
/// convergence log and, with `report`, the HTML report into that
/// directory.
pub fn calibrate_pose_dir(
    dir: &Path,
    out: Option<&Path>,
    flags: &CalibrateFlags,
    windows: bool,
    report: Option<&Path>,
) -> anyhow::Result<PoseFitted> {
    let refused = joint_only_flags(flags, windows);
    if !refused.is_empty() {
        bail!(
            "{}: {} a pose session (source = \"poses\", docs/model.md §7.9), which takes \
             --out and --knot-spacing",
            refused.join(", "),
            if refused.len() == 1 {
                "does not apply to"
            } else {
                "do not apply to"
            }
        );
    }
    if let Some(k) = flags.knot_spacing.filter(|k| !(k.is_finite() && *k > 0.0)) {
        bail!("--knot-spacing must be a positive number of seconds (got {k})");
    }
    let path = output_path(out, dir.join("result.json"))?;
    let session = load_pose_session(dir, |w| eprintln!("warning: {w}"))?;
    let mut options = pose_options(&session.meta, |w| eprintln!("warning: {w}"));
    options.knot_spacing = flags.knot_spacing;
    let mut stdout = std::io::stdout().lock();
    write_header(&mut stdout, dir, &session)?;
    let progress = Progress::start("calibrating the IMU from the poses");
    progress.println(IterationRecord::HEADER);
    let fitted = calibrate_pose_session(session, options, |e| match e {
        FitEvent::Iteration(r) => {
            progress.println(r.to_string());
            progress.set_message(format!("iteration {}: cost {:.6e}", r.iteration, r.cost));
        }
        FitEvent::Stage(s) => {
            progress.println(format!("-- {s}"));
            progress.set_message(s.to_string());
        }
    });
    progress.finish();
    let fitted = fitted?;
    print_fit(&mut stdout, &fitted)?;
    let history = fitted.write(&path)?;
    writeln!(stdout, "wrote {}", path.display())?;
    writeln!(stdout, "wrote {}", history.display())?;
    if let Some(dir) = report {
        let page = robimu_report::result_report::write_pose_fit_report(dir, &fitted)?;
        writeln!(stdout, "wrote {}", page.display())?;
    }
    Ok(fitted)
}

/// The first line: the session, its samples and what is estimated.
fn write_header(
    out: &mut impl Write,
    dir: &Path,
    session: &robimu_session::PoseSession,
) -> std::io::Result<()> {
    let (ta, tb) = session.poses.span().unwrap_or_default();
    let k = session.n_imus();
    let samples: Vec<String> = (session.imus.iter())
        .map(|f| f.samples.len().to_string())
        .collect();
    writeln!(
        out,
        "session {}: tool poses, {} poses, {} IMU samples{}, {:.1} s; estimating {} parameters \
         (IMU position, gravity, tau, 24 sensor parameters{})",
        dir.display(),
        session.poses.len(),
        samples.join(" + "),
        if k > 1 {
            format!(" ({k} IMUs)")
        } else {
            String::new()
        },
        tb - ta,
        robimu_session::pose_parameter_names(k).len(),
        if k > 1 { "; per IMU, g shared" } else { "" },
    )?;
    out.flush()
}

/// The verdict, a summary of the fit and the parameter table.
fn print_fit(out: &mut impl Write, fitted: &PoseFitted) -> anyhow::Result<()> {
    let (cal, result) = (&fitted.cal, &fitted.result);
    if let Some(v) = &result.verdict {
        write!(out, "{}", VerdictText(v))?;
    }
    writeln!(
        out,
        "start-up: tau = {:.4} s (angular-speed correlation {:.3}); knots every {:.3} s; \
         {} IMU samples in the fit",
        cal.startup.tau, cal.startup.correlation, cal.knot_spacing, cal.imu_used
    )?;
    writeln!(
        out,
        "pose residual RMS {:.3} mm, {:.3}° (σ_p {:.3} mm, σ_r {:.3}°)",
        cal.pose_rms[0] * 1e3,
        cal.pose_rms[1].to_degrees(),
        fitted.options.sigma_p * 1e3,
        fitted.options.sigma_r.to_degrees()
    )?;
    writeln!(out)?;
    write!(
        out,
        "{}",
        ParameterTable::new(result, fitted.session.truth.as_ref())
    )?;
    out.flush()?;
    Ok(())
}
