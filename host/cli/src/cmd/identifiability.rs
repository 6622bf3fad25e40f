//! `robimu identifiability`: how well a planned trajectory identifies x
//! (paper §8.2, §8.4).

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context};
use rand::SeedableRng;
use robimu_model::Spline;
use robimu_report::plot::{loglog_panels, LogLogPanel};
use robimu_workflows::identifiability::{
    baseline, check_approximation, error_moments, lambda_vs_time, length_sigma_vs_speed, median,
    monte_carlo_errors, sigma_vs_time, worst_direction, Baseline,
};
use robimu_workflows::plan::information::{covariance, Information, Sampling};
use robimu_workflows::plan::SplineFile;

use super::input::{resolve_robot, Progress};

/// Identifiability of a plan: σ against length and speed, against random trajectories.
///
/// Reads PLAN_DIR (spline.toml, else plan.csv, as `robimu plan` writes) and
/// writes to --out (default PLAN_DIR): sigma_vs_time.csv/.png/.svg (posterior
/// σ of every parameter against trajectory length, paper Fig. 6),
/// speed.csv/.png/.svg (σ of the robot length parameters for time-scaled
/// copies at equal sample count, Fig. 8), baselines.csv/.png/.svg (the
/// largest eigenvalue of Σ_x, SI, against time for the plan and random
/// trajectories of equal length under the same limits, Fig. 5). Prints the
/// ratios of λ_max(Σ_x) and the check of the approximation (26) against the
/// estimator's covariance (24) on the same plan.
#[derive(Debug, Clone, clap::Args)]
pub struct IdentifiabilityCmd {
    /// The plan directory.
    #[arg(long, value_name = "PLAN_DIR")]
    pub plan: PathBuf,
    /// Robot: a built-in name (aubo_i5) or the path of a TOML robot description.
    #[arg(long, default_value = "aubo_i5")]
    pub robot: String,
    /// Speed-up factors of the length study.
    #[arg(long, value_delimiter = ',', default_value = "1,2,4,8,16,32")]
    pub speeds: Vec<f64>,
    /// Random trajectories of each kind.
    #[arg(long, default_value_t = 10)]
    pub random: usize,
    /// IMU (and joint) sample rate, Hz.
    #[arg(long, default_value_t = 120.0)]
    pub rate: f64,
    /// Monte Carlo calibrations on the plan and on one random walk (0: none).
    #[arg(long, default_value_t = 0)]
    pub montecarlo: usize,
    /// Skip the check of (26) against the estimator's (24).
    #[arg(long)]
    pub no_check: bool,
    /// Seed of the random trajectories and the Monte Carlo runs.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Directory for the tables and figures [default: PLAN_DIR].
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// The plan's trajectory: spline.toml if present, else plan.csv refitted.
pub fn read_plan_spline(robot: &robimu_model::Robot, dir: &Path) -> anyhow::Result<Spline> {
    let path = dir.join("spline.toml");
    let spline = if path.is_file() {
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("cannot read {}", path.display()))?;
        let file: SplineFile = toml::from_str(&text)
            .with_context(|| format!("{}: not a spline file", path.display()))?;
        file.spline()
            .with_context(|| format!("{}: not a valid spline", path.display()))?
    } else {
        let path = dir.join("plan.csv");
        if !path.is_file() {
            bail!(
                "{}: no spline.toml or plan.csv (write one with `robimu plan --out {}`)",
                dir.display(),
                dir.display()
            );
        }
        let table = robimu_session::read_table(&path, robimu_session::Columns::Joints)?;
        robimu_model::trajectory::from_samples(table.width(), &table.t, &table.values)
            .with_context(|| format!("{}: cannot represent the plan", path.display()))?
    };
    if spline.dim() != robot.dof() {
        bail!(
            "{}: the plan has {} joints but robot `{}` has {}",
            dir.display(),
            spline.dim(),
            robot.name(),
            robot.dof()
        );
    }
    Ok(spline)
}

fn create(path: &Path) -> anyhow::Result<BufWriter<File>> {
    Ok(BufWriter::new(File::create(path).with_context(|| {
        format!("cannot write {}", path.display())
    })?))
}

impl IdentifiabilityCmd {
    /// Run the studies, write and print.
    pub fn run(self) -> anyhow::Result<()> {
        if !(self.rate.is_finite() && self.rate > 0.0 && self.rate <= 10_000.0) {
            bail!("--rate must be in (0, 10000] Hz (got {})", self.rate);
        }
        if let Some(s) = self.speeds.iter().find(|s| !(s.is_finite() && **s > 0.0)) {
            bail!("--speeds: {s} is not a positive speed-up factor");
        }
        let (robot, _) = resolve_robot(&self.robot, None)?;
        let spline = read_plan_spline(&robot, &self.plan)?;
        let dir = self.out.clone().unwrap_or_else(|| self.plan.clone());
        if !dir.is_dir() {
            bail!("--out {}: not a directory", dir.display());
        }
        let info = Information::new(&robot, robot.sigma_z(), self.rate)?;
        let layout = info.layout().clone();
        let duration = spline.knots().end() - spline.knots().start();
        let progress = Progress::start("identifiability");
        let mut out = std::io::stdout().lock();

        // Fig. 6: σ against length
        progress.set_message("posterior sigma against trajectory length");
        let (times, sig) = sigma_vs_time(&info, &spline, 5.0);
        let mut f = create(&dir.join("sigma_vs_time.csv"))?;
        let names: Vec<&str> = layout.specs().iter().map(|s| s.name.as_str()).collect();
        writeln!(f, "t,{}", names.join(","))?;
        for (t, row) in times.iter().zip(&sig) {
            let cols: Vec<String> = row.iter().map(|v| format!("{v:e}")).collect();
            writeln!(f, "{t},{}", cols.join(","))?;
        }
        f.flush()?;
        let group = |k: usize| -> usize {
            let name = &layout.specs()[k].name;
            if name.starts_with("eps") {
                0
            } else if ["g_", "tau", "r_"].iter().any(|p| name.starts_with(p)) {
                1
            } else {
                2
            }
        };
        let titles = [
            "robot errors eps (m, rad)",
            "g_xy, tau, r_a, r_w (SI)",
            "IMU intrinsics (SI)",
        ];
        let panels: Vec<LogLogPanel> = (0..3)
            .map(|g| LogLogPanel {
                title: titles[g].into(),
                x_label: "trajectory length [s]".into(),
                y_label: "posterior sigma".into(),
                series: (0..layout.len())
                    .filter(|&k| group(k) == g)
                    .map(|k| {
                        (
                            layout.specs()[k].name.clone(),
                            times.iter().zip(&sig).map(|(t, r)| (*t, r[k])).collect(),
                        )
                    })
                    .collect(),
            })
            .collect();
        loglog_panels(
            &dir.join("sigma_vs_time"),
            "Posterior sigma against trajectory length",
            &panels,
        )?;

        // Fig. 8: lengths against speed
        progress.set_message("robot length parameters against speed");
        let (lnames, rows) = length_sigma_vs_speed(&info, &spline, &self.speeds);
        let mut f = create(&dir.join("speed.csv"))?;
        writeln!(f, "speed,{}", lnames.join(","))?;
        writeln!(
            out,
            "robot length parameters: posterior sigma [mm] against speed"
        )?;
        writeln!(
            out,
            "{:>6} {}",
            "speed",
            lnames.iter().map(|n| format!("{n:>9}")).collect::<String>()
        )?;
        for (s, row) in self.speeds.iter().zip(&rows) {
            let cols: Vec<String> = row.iter().map(|v| format!("{v:e}")).collect();
            writeln!(f, "{s},{}", cols.join(","))?;
            writeln!(
                out,
                "{s:>6} {}",
                row.iter()
                    .map(|v| format!("{:>9.4}", v * 1e3))
                    .collect::<String>()
            )?;
        }
        f.flush()?;
        let panel = LogLogPanel {
            title: "robot length parameters".into(),
            x_label: "speed-up factor".into(),
            y_label: "posterior sigma [m]".into(),
            series: lnames
                .iter()
                .enumerate()
                .map(|(k, n)| {
                    (
                        n.clone(),
                        self.speeds
                            .iter()
                            .zip(&rows)
                            .map(|(s, r)| (*s, r[k]))
                            .collect(),
                    )
                })
                .collect(),
        };
        loglog_panels(
            &dir.join("speed"),
            "Length identifiability against speed",
            &[panel],
        )?;

        // Fig. 5: the plan against random trajectories
        let step = 5.0;
        let plan_curve = lambda_vs_time(&info, &spline, step);
        let mut rng = rand::rngs::StdRng::seed_from_u64(self.seed);
        let mut curves = Vec::new();
        for kind in [Baseline::Uniform, Baseline::RandomWalk] {
            let mut v = Vec::new();
            for k in 0..self.random {
                progress.set_message(format!(
                    "random trajectory {:?} {}/{}",
                    kind,
                    k + 1,
                    self.random
                ));
                let s = baseline(&robot, kind, duration, &mut rng)
                    .context("cannot make a random trajectory")?;
                v.push(lambda_vs_time(&info, &s, step));
            }
            curves.push(v);
        }
        let mut f = create(&dir.join("baselines.csv"))?;
        writeln!(
            f,
            "t,plan,plan_without_robot_lengths,uniform_median,uniform_median_without_robot_lengths,walk_median,walk_median_without_robot_lengths"
        )?;
        let med = |c: &Vec<Vec<(f64, f64, f64)>>, k: usize, nl: bool| -> f64 {
            let v: Vec<f64> = c
                .iter()
                .filter_map(|x| x.get(k).map(|p| if nl { p.2 } else { p.1 }))
                .collect();
            median(&v)
        };
        let mut series = vec![
            ("plan".to_string(), Vec::new()),
            ("uniform random (median)".to_string(), Vec::new()),
            ("random walk (median)".to_string(), Vec::new()),
        ];
        for (k, p) in plan_curve.iter().enumerate() {
            let (u, un) = (med(&curves[0], k, false), med(&curves[0], k, true));
            let (w, wn) = (med(&curves[1], k, false), med(&curves[1], k, true));
            writeln!(f, "{},{:e},{:e},{u:e},{un:e},{w:e},{wn:e}", p.0, p.1, p.2)?;
            series[0].1.push((p.0, p.1));
            series[1].1.push((p.0, u));
            series[2].1.push((p.0, w));
        }
        f.flush()?;
        loglog_panels(
            &dir.join("baselines"),
            "Largest eigenvalue of Sigma_x (SI) against time",
            &[LogLogPanel {
                title: "plan against random trajectories".into(),
                x_label: "time [s]".into(),
                y_label: "lambda_max(Sigma_x)".into(),
                series,
            }],
        )?;
        if let Some(end) = plan_curve.last() {
            let k = plan_curve.len() - 1;
            let (u, un) = (med(&curves[0], k, false), med(&curves[0], k, true));
            let (w, wn) = (med(&curves[1], k, false), med(&curves[1], k, true));
            writeln!(out, "lambda_max(Sigma_x) after {:.0} s, SI:", end.0)?;
            writeln!(
                out,
                "  plan {:.4e}; median of {} uniform random {u:.4e} (ratio {:.1}); median of {} random walks {w:.4e} (ratio {:.2})",
                end.1, self.random, u / end.1, self.random, w / end.1
            )?;
            writeln!(
                out,
                "  robot lengths known: plan {:.4e}; uniform {un:.4e} (ratio {:.1}); random walks {wn:.4e} (ratio {:.2})",
                end.2, un / end.2, wn / end.2
            )?;
        }

        // (26) against (24)
        if !self.no_check {
            progress.set_message("estimator covariance (24) on the plan");
            let h = spline.knots().knots()[spline.knots().degree() + 1] - spline.knots().start();
            let c = check_approximation(&robot, &spline, self.rate, h)
                .context("cannot compute the estimator's covariance on the plan")?;
            writeln!(
                out,
                "approximation (26) against the estimator's covariance (24): Frobenius norm of the difference {:.3e} (of {:.3e}); largest sigma ratio error {:.2} %",
                c.frobenius,
                c.norm,
                100.0 * c.max_sigma_ratio_error
            )?;
        }

        // Monte Carlo: the predicted gain in precision
        if self.montecarlo > 0 {
            let walk = baseline(&robot, Baseline::RandomWalk, duration, &mut rng)?;
            let all: Vec<usize> = (0..info.dim()).collect();
            let lam_plan = info.total(&spline, 1.0, Sampling::Exact);
            let lam_walk = info.total(&walk, 1.0, Sampling::Exact);
            let v = worst_direction(&lam_walk);
            let pred = |lam: &faer::Mat<f64>| -> anyhow::Result<(f64, f64)> {
                let c = covariance(lam, &all).context("singular information")?;
                let mut along = 0.0;
                for i in 0..all.len() {
                    for j in 0..all.len() {
                        along += v[i] * c[(i, j)] * v[j];
                    }
                }
                Ok((along, (0..all.len()).map(|i| c[(i, i)]).sum()))
            };
            let (pp, pw) = (pred(&lam_plan)?, pred(&lam_walk)?);
            let mut errs = Vec::new();
            for (name, s) in [("plan", &spline), ("random walk", &walk)] {
                let e = monte_carlo_errors(&robot, s, self.montecarlo, self.seed, |r| {
                    progress.set_message(format!(
                        "Monte Carlo on the {name}: run {r}/{}",
                        self.montecarlo
                    ))
                })
                .with_context(|| format!("Monte Carlo on the {name}"))?;
                errs.push(error_moments(&e, &v));
            }
            writeln!(
                out,
                "Monte Carlo, {} runs each: mean squared error along the random walk's worst direction: plan {:.3e} (predicted {:.3e}), random walk {:.3e} (predicted {:.3e}); gain {:.2} (predicted {:.2})",
                self.montecarlo, errs[0].0, pp.0, errs[1].0, pw.0, errs[1].0 / errs[0].0, pw.0 / pp.0
            )?;
            writeln!(
                out,
                "  total squared error (SI): plan {:.3e} (predicted trace {:.3e}), random walk {:.3e} (predicted {:.3e}); gain {:.2} (predicted {:.2})",
                errs[0].1, pp.1, errs[1].1, pw.1, errs[1].1 / errs[0].1, pw.1 / pp.1
            )?;
        }
        progress.finish();
        writeln!(
            out,
            "wrote sigma_vs_time, speed and baselines (.csv, .png, .svg) to {}",
            dir.display()
        )?;
        Ok(())
    }
}
