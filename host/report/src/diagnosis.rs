//! The text summary of a model-discrepancy diagnosis
//! ([`robimu_workflows::diagnose`]).

use std::fmt;

use robimu_model::IMU_CHANNELS as CHANNELS;
use robimu_workflows::diagnose::{
    AddedParameter, Diagnosis, FoundEffect, Rejected, ResidualStats, UNEXPLAINED_ALPHA,
};

use crate::fit_summary::EffectValue;
use crate::noise::NoiseChannels;

/// The parameters of an effect with a resolution (`<effect>.<channel>_k<i>`)
/// as one line per channel: its knot values in display units and the
/// largest σ.
fn write_knot_values(
    out: &mut fmt::Formatter<'_>,
    params: &[robimu_model::effects::EffectParam],
    values: &[AddedParameter],
) -> fmt::Result {
    let mut k = 0;
    while k < values.len() {
        let prefix = |n: &str| {
            n.rsplit_once('_')
                .map_or(n.to_string(), |(a, _)| a.to_string())
        };
        let head = prefix(&values[k].name);
        let end = (k..values.len())
            .find(|&e| prefix(&values[e].name) != head)
            .unwrap_or(values.len());
        let (unit, scale) = params
            .iter()
            .find(|p| p.name == values[k].name)
            .map_or(("", 1.0), |p| p.display);
        let knots: Vec<String> = values[k..end]
            .iter()
            .map(|p| format!("{:+.3}", p.value * scale))
            .collect();
        let sigma = values[k..end].iter().map(|p| p.sigma).fold(0.0, f64::max) * scale;
        writeln!(
            out,
            "   {head} at knots 1..{} [{unit}]: {} (σ ≤ {sigma:.3})",
            end - k,
            knots.join(" ")
        )?;
        k = end;
    }
    Ok(())
}

/// Which noise model the diagnosis used and why.
fn write_noise(out: &mut fmt::Formatter<'_>, d: &Diagnosis) -> fmt::Result {
    let n = &d.noise;
    let lb = n.white_test.as_ref().map(|id| {
        CHANNELS
            .iter()
            .zip(&id.channels)
            .map(|(c, ch)| format!("{c} {:.2e}", ch.ljung_box_p))
            .collect::<Vec<_>>()
            .join(", ")
    });
    let tests = "scores, refits and residual statistics on the prewhitened residuals";
    match (n.choice, &lb) {
        ("white", _) => writeln!(out, "noise model: white (--noise-model white)")?,
        ("given", _) => {
            writeln!(out, "noise model: given (generalised least squares; {tests}):")?;
            write!(out, "{}", NoiseChannels(&d.baseline.noise))?;
        }
        (_, Some(p)) if n.identified => {
            writeln!(
                out,
                "noise model: identified from the residuals of the white fit, which are not white (Ljung-Box p: {p}); {tests}:"
            )?;
            write!(out, "{}", NoiseChannels(&d.baseline.noise))?;
        }
        (_, Some(p)) if n.warnings.is_empty() => writeln!(
            out,
            "noise model: white (the white fit's residuals pass the Ljung-Box whiteness test, or no AR order or motion level is supported; p: {p})"
        )?,
        _ => writeln!(out, "noise model: white (not identified; see the warning)")?,
    }
    for e in &n.reidentified_after {
        writeln!(out, "noise model identified again after adding {e}")?;
    }
    if d.final_fit.noise != d.baseline.noise {
        writeln!(out, "final noise model:")?;
        write!(out, "{}", NoiseChannels(&d.final_fit.noise))?;
    }
    for w in &n.warnings {
        writeln!(out, "warning: {w}")?;
    }
    Ok(())
}

/// Channel display: whitened RMS × σ in physical units (m/s², °/s).
fn physical_rms(rms: &[f64; 6], sigma: &[f64; 6]) -> [f64; 6] {
    std::array::from_fn(|c| {
        let s = if c < 3 {
            1.0
        } else {
            180.0 / std::f64::consts::PI
        };
        rms[c] * sigma[c] * s
    })
}

/// The summary `robimu diagnose` prints: the baseline's residual
/// statistics, each effect found (score and refit tests, its parameters,
/// the residual RMS before and after, the baseline parameters it moved),
/// the residual RMS before and after in physical units, the final model and
/// what structure remains.
pub struct DiagnosisSummary<'a>(pub &'a Diagnosis);

impl fmt::Display for DiagnosisSummary<'_> {
    fn fmt(&self, out: &mut fmt::Formatter<'_>) -> fmt::Result {
        let d = self.0;
        write_noise(out, d)?;
        write_baseline(out, d)?;
        for (k, f) in d.found.iter().enumerate() {
            write_found(out, d, k, f)?;
        }
        for r in &d.rejected {
            write_rejected(out, r)?;
        }
        write_rms_change(out, d)?;
        writeln!(
            out,
            "final model: baseline + [{}]",
            d.final_specs().join(", ")
        )?;
        write_stats(out, &d.stats_after)?;
        write_structure_left(out, d)?;
        write_unexplained(out, d)
    }
}

/// The level of a per-channel test: [`UNEXPLAINED_ALPHA`], Bonferroni over
/// the channels (the Ljung–Box p below which a channel's residuals count as
/// not white, and the unexplained structure's level).
fn per_channel_alpha() -> f64 {
    UNEXPLAINED_ALPHA / CHANNELS.len() as f64
}

/// The baseline's fit and residual statistics (and, when nothing was
/// found, that nothing is significant).
fn write_baseline(out: &mut fmt::Formatter<'_>, d: &Diagnosis) -> fmt::Result {
    let before = &d.stats_before;
    writeln!(
        out,
        "baseline: {} IMU samples, chi2 {:.0} for {} dof ({:.3} per dof)",
        before.samples,
        before.chi2_total.0,
        before.chi2_total.1,
        before.chi2_total.0 / before.chi2_total.1.max(1) as f64
    )?;
    write_stats(out, before)?;
    if d.found.is_empty() {
        writeln!(
            out,
            "no catalogued effect is significant (Bonferroni threshold p < {:.2e})",
            d.threshold
        )?;
    }
    Ok(())
}

/// The `k`-th effect found: its name (whose, what it is ambiguous with),
/// tests, resolution, parameters, residual RMS before and after and the
/// baseline parameters it moved.
fn write_found(
    out: &mut fmt::Formatter<'_>,
    d: &Diagnosis,
    k: usize,
    f: &FoundEffect,
) -> fmt::Result {
    writeln!(
        out,
        "\n{}. missing effect: {}  (score {:.1}, {} dof, p = {:.2e}; refit LR {:.1}, p = {:.2e}, dBIC {:.1})",
        k + 1,
        found_name(d, f),
        f.statistic,
        f.dof,
        f.p_value,
        f.lr_statistic,
        f.lr_p_value,
        f.delta_bic
    )?;
    if let Some(r) = &f.resolution {
        let table: Vec<String> = r
            .candidates
            .iter()
            .map(|c| {
                format!(
                    "M={} score {:.1} AIC {:.1}",
                    c.resolution, c.statistic, c.aic
                )
            })
            .collect();
        writeln!(
            out,
            "   resolution {} segments by AIC (at most {}; refit with --effects {}): {}",
            r.chosen,
            r.max,
            r.spec,
            table.join(", ")
        )?;
    }
    write_found_parameters(out, d, f)?;
    let rb = f.rms_before;
    let ra = f.rms_after;
    let line: Vec<String> = CHANNELS
        .iter()
        .enumerate()
        .map(|(c, n)| format!("{n} {:.3}→{:.3}", rb[c], ra[c]))
        .collect();
    writeln!(out, "   whitened residual rms: {}", line.join("  "))?;
    if !f.baseline_moves.is_empty() {
        let moves: Vec<String> = f
            .baseline_moves
            .iter()
            .map(|m| {
                format!(
                    "{} {:.4e}→{:.4e} (σ {:.1e})",
                    m.name, m.before, m.after, m.sigma
                )
            })
            .collect();
        writeln!(
            out,
            "   baseline parameters moved > 1σ: {}",
            moves.join(", ")
        )?;
    }
    Ok(())
}

/// An effect's name as listed: with several IMUs whose it is (docs/model.md
/// §9), and the alternatives it is ambiguous with.
fn found_name(d: &Diagnosis, f: &FoundEffect) -> String {
    let ambiguous: Vec<String> = f
        .alternatives
        .iter()
        .filter(|a| a.ambiguous)
        .map(|a| {
            format!(
                "{}: S({b}|{a}) = {:.1}, p = {:.2e}; S({a}|{b}) = {:.1}, p = {:.2e}",
                a.name,
                a.given_winner,
                a.given_winner_p,
                a.winner_given_it,
                a.winner_given_it_p,
                a = f.name,
                b = a.name,
            )
        })
        .collect();
    let k_imus = d.final_fit.n_imus;
    let whose = match f.imu {
        _ if k_imus <= 1 => String::new(),
        Some(j) => format!(" [IMU {j}]"),
        None => format!(" [shared by the {k_imus} IMUs]"),
    };
    if ambiguous.is_empty() {
        format!("{}{whose}", f.name)
    } else {
        format!(
            "{}{whose} (ambiguous with {})",
            f.name,
            ambiguous.join("; ")
        )
    }
}

/// An effect's parameters in display units: one line per channel (its
/// knot values) for an effect with a resolution, else one per parameter.
fn write_found_parameters(
    out: &mut fmt::Formatter<'_>,
    d: &Diagnosis,
    f: &FoundEffect,
) -> fmt::Result {
    let params = &d.final_fit.effect_params;
    if f.resolution.is_some() {
        return write_knot_values(out, params, &f.parameters);
    }
    for a in &f.parameters {
        let display = params
            .iter()
            .find(|p| p.name == a.name)
            .map_or(("", 1.0), |p| p.display);
        let value = EffectValue {
            name: &a.name,
            value: a.value,
            sigma: a.sigma,
            display,
        };
        writeln!(out, "   {value}")?;
    }
    Ok(())
}

/// A candidate not added, and why.
fn write_rejected(out: &mut fmt::Formatter<'_>, r: &Rejected) -> fmt::Result {
    let lr = if r.lr_statistic.is_finite() {
        format!("; refit LR {:.1}", r.lr_statistic)
    } else {
        String::new()
    };
    writeln!(
        out,
        "\nnot added: {} (score {:.1}, {} dof, p = {:.2e}{lr}): {}",
        r.name, r.statistic, r.dof, r.p_value, r.reason
    )
}

/// The residual RMS of the baseline and of the final model in physical
/// units.
fn write_rms_change(out: &mut fmt::Formatter<'_>, d: &Diagnosis) -> fmt::Result {
    let sz = d.sigma_z;
    let pb = physical_rms(&d.baseline.residual_rms(), &sz);
    let pa = physical_rms(&d.final_fit.residual_rms(), &sz);
    writeln!(
        out,
        "\nresidual rms before → after: accel {:.3}/{:.3}/{:.3} → {:.3}/{:.3}/{:.3} m/s^2, gyro {:.3}/{:.3}/{:.3} → {:.3}/{:.3}/{:.3} deg/s",
        pb[0], pb[1], pb[2], pa[0], pa[1], pa[2], pb[3], pb[4], pb[5], pa[3], pa[4], pa[5]
    )
}

/// The structure left in the final residuals that no candidate explains
/// (the channels failing the Ljung–Box test), or that they are white.
fn write_structure_left(out: &mut fmt::Formatter<'_>, d: &Diagnosis) -> fmt::Result {
    let lb_threshold = per_channel_alpha();
    let left: Vec<String> = d
        .stats_after
        .ljung_box
        .iter()
        .filter(|(_, (_, p))| *p < lb_threshold)
        .map(|(c, _)| {
            let (f, pk) = d.stats_after.spectral_peak[c].unwrap_or_default();
            let (r, corr, z) = d
                .stats_after
                .top_regressor
                .get(c)
                .cloned()
                .unwrap_or_default();
            format!("{c} (peak {f:.2} Hz at {pk:.0}× median power; follows {r}, r = {corr:+.3}, z = {z:.1})")
        })
        .collect();
    if left.is_empty() {
        writeln!(
            out,
            "residuals are white in every channel (Ljung–Box, p ≥ {lb_threshold:.1e})"
        )
    } else {
        writeln!(
            out,
            "structure remains that no candidate explains: {}",
            left.join("; ")
        )
    }
}

/// The unexplained structure the diagnosis flagged: narrow spectral peaks
/// and correlations with regressors no effect explains.
fn write_unexplained(out: &mut fmt::Formatter<'_>, d: &Diagnosis) -> fmt::Result {
    if d.unexplained.is_empty() {
        return Ok(());
    }
    let items: Vec<String> = d.unexplained.iter().map(|u| u.describe(true)).collect();
    writeln!(
        out,
        "unexplained structure (a narrow spectral peak the noise model does not capture, or a correlation with a regressor no effect explains; p < {:.1e} each): {}",
        per_channel_alpha(),
        items.join("; ")
    )
}

/// The per-channel table of residual statistics.
fn write_stats(out: &mut fmt::Formatter<'_>, s: &ResidualStats) -> fmt::Result {
    writeln!(
        out,
        "  {:<4} {:>7} {:>10} {:>10} {:>9} {:>10} {:>12}",
        "ch", "rms", "LjungBox", "p", "peak Hz", "peak/med", "top regressor"
    )?;
    for c in CHANNELS {
        let (q, p) = s.ljung_box[c];
        let (f, pk) = s.spectral_peak[c].unwrap_or_default();
        let (r, corr, _) = s.top_regressor.get(c).cloned().unwrap_or_default();
        writeln!(
            out,
            "  {:<4} {:>7.3} {:>10.1} {:>10.2e} {:>9.2} {:>10.1} {:>6} {:+.3}",
            c, s.rms[c], q, p, f, pk, r, corr
        )?;
    }
    Ok(())
}
