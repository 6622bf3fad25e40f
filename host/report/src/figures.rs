//! The calibration report's figures built from a result: the σ reduction
//! per parameter (bars by name, grouped, log scale) and the IMU residuals
//! with the noise model's ±1σ band (docs/model.md §4.6).

use std::path::{Path, PathBuf};

use crate::plot::{banded_line_panels, log_bars, Band, Bar, BarGroup, LinePanel, PlotError};
use robimu_session::result::{CalibrationResult, NoiseModelRecord, ParameterResult};

/// The groups of the σ-reduction figure, in x order (docs/model.md §5).
pub(crate) const GROUPS: [&str; 5] = [
    "robot",
    "IMU position, gravity, time offset",
    "accelerometer",
    "gyroscope",
    "effects",
];

/// `eps_<i>_<k>` as (i, k).
fn error_indices(name: &str) -> Option<(usize, usize)> {
    let rest = name.strip_prefix("eps_")?;
    let (i, k) = rest.split_once('_')?;
    Some((i.parse().ok()?, k.parse().ok()?))
}

/// The group (index into [`GROUPS`]) of parameter `name`; `imu_link` is the
/// last link n, whose errors k = 1..3 are the IMU position (§1.4).
pub(crate) fn parameter_group(name: &str, imu_link: usize) -> usize {
    if let Some((i, k)) = error_indices(name) {
        return if i == imu_link && k <= 3 { 1 } else { 0 };
    }
    if name.starts_with("g_") || name == "tau" {
        1
    } else if name.contains("_a_") {
        2
    } else if name.contains("_w_") {
        3
    } else {
        4
    }
}

/// A parameter's bar: posterior σ / prior σ by its name; frozen parameters
/// and those without a σ without a bar.
fn sigma_bar(p: &ParameterResult) -> Bar {
    let ratio = p.sigma / p.prior_sigma;
    let (value, note) = if p.frozen {
        (None, "frozen")
    } else if ratio.is_finite() && ratio > 0.0 {
        (Some(ratio), "")
    } else {
        (None, "no σ")
    };
    Bar {
        label: p.name.clone(),
        value,
        note: note.into(),
    }
}

/// The bars of the σ-reduction figure: every parameter of `result` by name
/// with its posterior σ / prior σ, grouped as [`GROUPS`] (empty groups left
/// out); frozen parameters and those without a σ are listed without a bar.
pub(crate) fn sigma_reduction_groups(result: &CalibrationResult) -> Vec<BarGroup> {
    let imu_link = result
        .parameters
        .iter()
        .filter_map(|p| error_indices(&p.name).map(|(i, _)| i))
        .max()
        .unwrap_or(0);
    let mut groups: Vec<BarGroup> = GROUPS
        .iter()
        .map(|g| BarGroup {
            name: g.to_string(),
            bars: Vec::new(),
        })
        .collect();
    for p in &result.parameters {
        groups[parameter_group(&p.name, imu_link)]
            .bars
            .push(sigma_bar(p));
    }
    groups.retain(|g| !g.bars.is_empty());
    groups
}

/// [`sigma_reduction_groups`] for a result of several IMUs (docs/model.md
/// §9): the shared robot errors, gravity and shared effects, then per IMU
/// j its position and time offset, accelerometer, gyroscope and effects
/// (`IMU j: …`), empty groups left out. `None` for a one-IMU result.
pub(crate) fn sigma_reduction_groups_by_imu(result: &CalibrationResult) -> Option<Vec<BarGroup>> {
    let sets = result.imu_sets().ok().filter(|s| s.len() > 1)?;
    let bar = |i: usize| sigma_bar(&result.parameters[i]);
    let base = |i: usize| {
        let n = &result.parameters[i].name;
        robimu_session::result::split_imu_name(n).map_or(n.as_str(), |(_, b)| b)
    };
    let mut groups = Vec::new();
    let mut shared = [
        ("robot", Vec::new()),
        ("gravity", Vec::new()),
        ("effects", Vec::new()),
    ];
    for &i in &sets.shared {
        let g = match parameter_group(base(i), sets.imu_link) {
            0 => 0,
            1 => 1,
            _ => 2,
        };
        shared[g].1.push(bar(i));
    }
    for (name, bars) in shared {
        groups.push(BarGroup {
            name: name.into(),
            bars,
        });
    }
    for (j, set) in sets.imus.iter().enumerate() {
        let mut own: Vec<BarGroup> = [
            "position, time offset",
            "accelerometer",
            "gyroscope",
            "effects",
        ]
        .iter()
        .map(|g| BarGroup {
            name: format!("IMU {j}: {g}"),
            bars: Vec::new(),
        })
        .collect();
        for &i in set {
            let g = match parameter_group(base(i), sets.imu_link) {
                0 | 1 => 0,
                2 => 1,
                3 => 2,
                _ => 3,
            };
            own[g].bars.push(bar(i));
        }
        groups.extend(own);
    }
    groups.retain(|g| !g.bars.is_empty());
    Some(groups)
}

/// `stem.{png,svg}`: the σ-reduction figure of `result`.
pub(crate) fn sigma_reduction_figure(
    stem: &Path,
    result: &CalibrationResult,
) -> Result<Vec<PathBuf>, PlotError> {
    log_bars(
        stem,
        "Posterior σ relative to the prior σ, by parameter",
        "posterior σ / prior σ (log scale; 1 = not reduced)",
        1.0,
        &sigma_reduction_groups_by_imu(result).unwrap_or_else(|| sigma_reduction_groups(result)),
    )
}

/// The IMU noise level drawn as the residuals' ±1σ band: per channel
/// `[ax, ay, az, gx, gy, gz]` the σ at rest (SI) and the motion gain c of
/// σ²(t) = σ² + c‖q̈(t + τ)‖² (docs/model.md §4.6).
#[derive(Debug, Clone, PartialEq)]
pub struct NoiseBand {
    /// σ per channel, m/s² or rad/s.
    pub sigma: [f64; 6],
    /// Motion gain per channel, the channel's unit² per (rad/s²)².
    pub motion: [f64; 6],
    /// Which model this is, for the caption.
    pub source: String,
}

impl NoiseBand {
    /// The noise model a fit used: the result's AR model (`noise_model`,
    /// §8.2) when it has one, else white noise of `sigma_z` (the σ the fit
    /// was given).
    pub fn of_fit(model: Option<&NoiseModelRecord>, sigma_z: &[f64; 6]) -> Self {
        match model {
            Some(NoiseModelRecord::Ar { channels }) if channels.len() == 6 => {
                let mut band = Self {
                    sigma: [0.0; 6],
                    motion: [0.0; 6],
                    source: "the fit's AR noise model (marginal σ and its motion level)".into(),
                };
                for (c, ch) in channels.iter().enumerate() {
                    band.sigma[c] = ch.sigma;
                    band.motion[c] = ch.motion.max(0.0);
                }
                band
            }
            _ => Self {
                sigma: *sigma_z,
                motion: [0.0; 6],
                source: "the fit's white noise (sigma_z)".into(),
            },
        }
    }

    /// σ of channel `c` at squared joint-acceleration norm `qdd2`, SI.
    pub fn sigma_at(&self, c: usize, qdd2: f64) -> f64 {
        (self.sigma[c].powi(2) + self.motion[c] * qdd2).sqrt()
    }
}

/// Channel names and display units of the residual figure.
pub const CHANNELS: [(&str, &str); 6] = [
    ("ax", "m/s^2"),
    ("ay", "m/s^2"),
    ("az", "m/s^2"),
    ("gx", "deg/s"),
    ("gy", "deg/s"),
    ("gz", "deg/s"),
];

fn rms(v: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    (sum / n.max(1) as f64).sqrt()
}

/// `stem.{png,svg}`: one panel per IMU channel, the residuals (t, r) with
/// the ±σ(t) band (t, σ) around zero, both in display units (m/s², °/s);
/// the title states τ in ms.
pub(crate) fn residual_figure(
    stem: &Path,
    residuals: &[Vec<(f64, f64)>],
    band: &[Vec<(f64, f64)>],
    tau: f64,
) -> Result<Vec<PathBuf>, PlotError> {
    let mut panels = Vec::new();
    for (c, pts) in residuals.iter().enumerate().take(6) {
        let (name, unit) = CHANNELS[c];
        let sigma = band.get(c).filter(|b| !b.is_empty());
        let mut title = format!("{name}: RMS {:.3}", rms(pts.iter().map(|p| p.1)));
        if let Some(b) = sigma {
            title.push_str(&format!(", noise σ {:.3}", rms(b.iter().map(|p| p.1))));
        }
        title.push_str(&format!(" {unit}"));
        let panel = LinePanel {
            title,
            x_label: "t [s]".into(),
            y_label: unit.into(),
            series: vec![(format!("{name} residual"), pts.clone())],
        };
        let band = sigma.map(|b| Band {
            label: "±1σ noise".into(),
            points: b.iter().map(|&(t, s)| (t, -s, s)).collect(),
        });
        panels.push((panel, band));
    }
    let refs: Vec<(&LinePanel, Option<&Band>)> =
        panels.iter().map(|(p, b)| (p, b.as_ref())).collect();
    banded_line_panels(
        stem,
        &format!(
            "IMU residuals, measured − predicted at the estimate (τ = {:.2} ms)",
            1e3 * tau
        ),
        &refs,
        3,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::{histogram_grid, line_panels, loglog_panels, HistogramPanel, LogLogPanel};
    use ab_glyph::{Font, FontRef, GlyphId, PxScale, ScaleFont};
    use robimu_model::{ParamLayout, Robot};
    use robimu_session::result::CalibrationResult;

    fn font() -> FontRef<'static> {
        FontRef::try_from_slice(crate::plot::FONT).expect("the embedded font parses")
    }

    /// The text of every `<text>` element of an SVG: plotters writes one per
    /// string it draws (titles, axis and tick labels, legends).
    fn svg_texts(svg: &str) -> Vec<String> {
        let mut out = Vec::new();
        let mut rest = svg;
        while let Some(start) = rest.find("<text") {
            let open = start + rest[start..].find('>').expect("a closed tag") + 1;
            let end = open + rest[open..].find("</text>").expect("</text>");
            let raw = rest[open..end].trim_matches('\n');
            out.push(
                raw.replace("&lt;", "<")
                    .replace("&gt;", ">")
                    .replace("&quot;", "\"")
                    .replace("&apos;", "'")
                    .replace("&amp;", "&"),
            );
            rest = &rest[end..];
        }
        out
    }

    /// The characters of `text` the font has no glyph for (GlyphId 0).
    fn missing_glyphs(font: &FontRef<'_>, text: &str) -> Vec<char> {
        text.chars()
            .filter(|&c| font.glyph_id(c) == GlyphId(0))
            .collect()
    }

    /// A result with every AUBO i5 parameter (docs/model.md §6.3), σ a
    /// fraction of the prior σ, the robot lengths frozen, parsed from JSON.
    fn aubo_result() -> CalibrationResult {
        let robot = Robot::aubo_i5();
        let layout = ParamLayout::new(&robot);
        let n = robot.dof();
        let frozen = |k: usize| {
            layout
                .estimated_errors()
                .get(k)
                .is_some_and(|e| e.is_length(n) && e.link < n)
        };
        let mut params = Vec::new();
        let mut names = Vec::new();
        for (k, s) in layout.specs().iter().enumerate() {
            let ratio = 10f64.powf(-(k as f64) / 16.0);
            let f = frozen(k);
            params.push(serde_json::json!({
                "name": s.name, "unit": s.unit, "value": s.nominal, "prior": s.nominal,
                "prior_sigma": s.sigma, "sigma": if f { 0.0 } else { ratio * s.sigma }, "frozen": f,
            }));
            if !f {
                names.push((s.name.clone(), ratio * s.sigma));
            }
        }
        let matrix: Vec<Vec<f64>> = (0..names.len())
            .map(|i| {
                (0..names.len())
                    .map(|j| if i == j { names[i].1.powi(2) } else { 0.0 })
                    .collect()
            })
            .collect();
        let json = serde_json::json!({
            "format": "robimu-result/1",
            "parameters": params,
            "covariance": {"names": names.iter().map(|n| &n.0).collect::<Vec<_>>(), "matrix": matrix},
        });
        CalibrationResult::parse(&json.to_string(), Path::new("result.json")).unwrap()
    }

    #[test]
    fn sigma_bars_are_the_model_names_in_their_groups() {
        let result = aubo_result();
        let groups = sigma_reduction_groups(&result);
        // docs/model.md §6.3: 0–17 robot, 18–23 IMU position, g, τ,
        // 24–35 accelerometer, 36–47 gyroscope
        let sizes: Vec<(&str, usize)> = groups
            .iter()
            .map(|g| (g.name.as_str(), g.bars.len()))
            .collect();
        assert_eq!(
            sizes,
            [
                ("robot", 18),
                ("IMU position, gravity, time offset", 6),
                ("accelerometer", 12),
                ("gyroscope", 12)
            ]
        );
        let bars: Vec<&Bar> = groups.iter().flat_map(|g| &g.bars).collect();
        for (bar, p) in bars.iter().zip(&result.parameters) {
            assert_eq!(bar.label, p.name);
            match bar.value {
                Some(v) => assert!((v - p.sigma / p.prior_sigma).abs() < 1e-12 * v),
                None => assert!(p.frozen && bar.note == "frozen", "{}", p.name),
            }
        }
        assert_eq!(bars[18].label, "eps_6_1");
        assert_eq!(bars[23].label, "tau");
        assert_eq!(bars[24].label, "gamma_a_yz");
        // the robot lengths ε_i{1,2,3} of the links before the last
        assert_eq!(bars.iter().filter(|b| b.value.is_none()).count(), 9);
    }

    /// Two and three IMUs: the shared groups, then each IMU's (position
    /// and τ 4, accelerometer 12, gyroscope 12 bars), every parameter
    /// once; a one-IMU result keeps the one-IMU groups.
    #[test]
    fn sigma_bars_of_several_imus_are_grouped_by_imu() {
        let dir = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../cli/tests/fixtures/multi_imu"
        ));
        let one = CalibrationResult::read(&dir.join("result1.json")).unwrap();
        assert!(sigma_reduction_groups_by_imu(&one).is_none());
        for k in [2usize, 3] {
            let r = CalibrationResult::read(&dir.join(format!("result{k}.json"))).unwrap();
            let groups = sigma_reduction_groups_by_imu(&r).unwrap();
            let mut want = vec![("robot".to_string(), 18), ("gravity".to_string(), 2)];
            for j in 0..k {
                want.push((format!("IMU {j}: position, time offset"), 4));
                want.push((format!("IMU {j}: accelerometer"), 12));
                want.push((format!("IMU {j}: gyroscope"), 12));
            }
            let sizes: Vec<(String, usize)> = groups
                .iter()
                .map(|g| (g.name.clone(), g.bars.len()))
                .collect();
            assert_eq!(sizes, want);
            for g in &groups[2..] {
                let j: usize = g.name[4..5].parse().unwrap();
                for b in &g.bars {
                    assert_eq!(
                        b.label.starts_with(&format!("imu{j}/")),
                        j > 0,
                        "{}",
                        b.label
                    );
                    let p = r.parameter(&b.label).unwrap();
                    assert_eq!(b.value.is_none(), p.frozen);
                    if let Some(v) = b.value {
                        assert!((v - p.sigma / p.prior_sigma).abs() < 1e-12 * v);
                    }
                }
            }
            let tmp = tempfile::tempdir().unwrap();
            let files = sigma_reduction_figure(&tmp.path().join("s"), &r).unwrap();
            let svg = std::fs::read_to_string(&files[1]).unwrap();
            let texts = svg_texts(&svg);
            for must in ["IMU 2: gyroscope", "imu1/k_a_x", "g_y"] {
                if must.contains('2') && k < 3 {
                    continue;
                }
                assert!(texts.iter().any(|t| t == must), "no `{must}`");
            }
            let font = font();
            assert!(texts.iter().all(|t| missing_glyphs(&font, t).is_empty()));
        }
    }

    #[test]
    fn every_string_a_figure_draws_has_a_glyph() {
        let font = font();
        // the check finds a missing glyph: the former residual title's ẑ
        assert_eq!(
            missing_glyphs(&font, "IMU residuals z − ẑ(x)"),
            ['ẑ'],
            "the subset lacks ẑ (U+1E91)"
        );
        assert_eq!(missing_glyphs(&font, "z\u{302}"), ['\u{302}']);
        let dir = tempfile::tempdir().unwrap();
        let mut svgs = Vec::new();
        let result = aubo_result();
        svgs.push(sigma_reduction_figure(&dir.path().join("sigma"), &result).unwrap()[1].clone());
        let res: Vec<Vec<(f64, f64)>> = (0..6)
            .map(|c| {
                (0..50)
                    .map(|i| (i as f64 * 0.1, ((i * (c + 3)) % 7) as f64 - 3.0))
                    .collect()
            })
            .collect();
        let band: Vec<Vec<(f64, f64)>> = res
            .iter()
            .map(|s| s.iter().map(|&(t, _)| (t, 1.0 + 0.1 * t)).collect())
            .collect();
        svgs.push(
            residual_figure(&dir.path().join("res"), &res, &band, 0.0123).unwrap()[1].clone(),
        );
        // the other figure kinds of the reports, with their kinds of text
        let line = LinePanel {
            title: "MAP cost J per iteration".into(),
            x_label: "iteration".into(),
            y_label: "log10 J".into(),
            series: vec![
                ("J".into(), vec![(0.0, 4.0), (3.0, 2.0)]),
                ("q1".into(), vec![]),
            ],
        };
        svgs.push(
            line_panels(&dir.path().join("line"), "Joint trajectory", &[line], 1).unwrap()[1]
                .clone(),
        );
        let hist = HistogramPanel {
            title: "calibrated (this method): |Δω| [deg/s]".into(),
            values: (0..40).map(|i| i as f64).collect(),
            normal: Some((20.0, 8.0)),
        };
        svgs.push(
            histogram_grid(&dir.path().join("hist"), "IMU accuracy", &[hist], 1).unwrap()[1]
                .clone(),
        );
        let ll = LogLogPanel {
            title: "gyroscope".into(),
            x_label: "tau [s]".into(),
            y_label: "PSD [whitened²/Hz]".into(),
            series: vec![("gx".into(), vec![(0.1, 1.0), (10.0, 0.1)])],
        };
        svgs.push(
            loglog_panels(&dir.path().join("ll"), "Allan deviation", &[ll]).unwrap()[1].clone(),
        );
        let mut all = Vec::new();
        for svg in &svgs {
            all.extend(svg_texts(&std::fs::read_to_string(svg).unwrap()));
        }
        for must in [
            "eps_2_4",
            "gamma_a_yz",
            "b_w_z",
            "frozen",
            "accelerometer",
            "IMU residuals, measured − predicted at the estimate (τ = 12.30 ms)",
            "±1σ noise",
            "posterior σ / prior σ (log scale; 1 = not reduced)",
        ] {
            assert!(all.iter().any(|t| t == must), "no text `{must}` in {all:?}");
        }
        let bad: Vec<(String, Vec<char>)> = all
            .iter()
            .map(|t| (t.clone(), missing_glyphs(&font, t)))
            .filter(|(_, m)| !m.is_empty())
            .collect();
        assert!(
            bad.is_empty(),
            "strings with characters the font lacks: {bad:?}"
        );
    }

    #[test]
    fn residual_title_is_inked_glyph_by_glyph() {
        let dir = tempfile::tempdir().unwrap();
        let res = vec![vec![(0.0, -1.0), (1.0, 1.0)]; 6];
        let band = vec![vec![(0.0, 0.5), (1.0, 0.5)]; 6];
        let files = residual_figure(&dir.path().join("res"), &res, &band, -0.00216).unwrap();
        let img = image::open(&files[0]).unwrap().to_luma8();
        let title = "IMU residuals, measured − predicted at the estimate (τ = -2.16 ms)";
        // where each glyph lands: plotters centres the title, advancing by
        // ab_glyph's advances and kerning at 22 px (plot::draw_lines)
        let font = font();
        let scaled = font.as_scaled(PxScale::from(22.0));
        let width: f32 = title
            .chars()
            .scan(None, |prev, c| {
                let id = scaled.glyph_id(c);
                let kern = prev.map_or(0.0, |p| scaled.kern(p, id));
                *prev = Some(id);
                Some(scaled.h_advance(id) + kern)
            })
            .sum();
        let ink = |xa: i32, xb: i32| {
            (xa.max(0)..=xb.min(img.width() as i32 - 1))
                .flat_map(|x| (0..36).map(move |y| (x, y)))
                .filter(|&(x, y)| img.get_pixel(x as u32, y).0[0] < 160)
                .count()
        };
        // the title is centred: its first ink within a few px of where the
        // layout puts it; the glyphs are then placed from that first ink
        let centred = img.width() as i32 / 2 - width as i32 / 2;
        let first = (0..img.width() as i32).find(|&x| ink(x, x) > 0).unwrap();
        let first_bearing = scaled
            .outline_glyph(scaled.scaled_glyph('I'))
            .unwrap()
            .px_bounds()
            .min
            .x as i32;
        let x0 = first - first_bearing;
        assert!(
            (x0 - centred).abs() <= 3,
            "title starts at {x0}, centred {centred}"
        );
        let mut shift = 0f32;
        let mut prev = None;
        let mut inked = 0;
        for c in title.chars() {
            let id = scaled.glyph_id(c);
            if let Some(p) = prev {
                shift += scaled.kern(p, id);
            }
            prev = Some(id);
            if let Some(outline) = scaled.outline_glyph(scaled.scaled_glyph(c)) {
                let b = outline.px_bounds();
                // ±1 px: plotters rounds each glyph's position
                let (xa, xb) = (
                    x0 + shift as i32 + b.min.x as i32 - 1,
                    x0 + shift as i32 + b.max.x as i32 + 1,
                );
                let cols: Vec<i32> = (xa - 6..xb + 6).filter(|&x| ink(x, x) > 0).collect();
                assert!(
                    ink(xa, xb) > 0,
                    "no ink for `{c}` at x {xa}..{xb}: {cols:?}"
                );
                inked += 1;
            }
            shift += scaled.h_advance(id);
        }
        assert_eq!(inked, title.chars().filter(|c| *c != ' ').count());
        // and nothing beyond the title's ends
        assert_eq!(ink(0, x0 - 3), 0);
        assert_eq!(ink(x0 + width as i32 + 3, img.width() as i32), 0);
    }
}
