//! Making a recording's files whole: after a crash or a kill (`robimu
//! repair`), and at the end of every recording.
//!
//! * A CSV whose last line was cut mid-write loses that line.
//! * `imu.csv` rows carry the device time and clock segment they were
//!   stamped with (`t_device`, `segment` columns); their session times are
//!   recomputed from every ping echo in `pings.csv` with the final robust
//!   clock fit of each segment ([`ClockFit`]), replacing the provisional
//!   times the recorder wrote while the fit was still growing.
//! * With several IMUs (docs/model.md §9), every `imu<j>.csv` likewise,
//!   from the ping log of its board (its `[imu<j>]` table's `pings`,
//!   [`pings_file`]; `pings.csv` when none is named).
//! * `joints.csv` rows of a UR recording carry the controller's timestamp
//!   and the host's arrival time (`t_robot`, `t_arrival` columns); their
//!   session times are recomputed from `t_robot` with the lower-envelope
//!   fit of [`super::robot_clock`], which `session.toml`'s
//!   `[controller]` table records.

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use super::clock_fit::{ClockFit, Echo};
use super::robot_clock::{self, RobotClockFit};
use robimu_session::{files, SessionError, SessionMeta};

/// Name of the ping log in a recorded session.
pub(crate) const PINGS: &str = "pings.csv";
/// The ping log of board `b` of a recording: [`PINGS`] for the first,
/// `pings<b>.csv` for the others.
pub(crate) fn pings_file(b: usize) -> String {
    if b == 0 {
        PINGS.to_string()
    } else {
        format!("pings{b}.csv")
    }
}

/// Header of [`PINGS`].
pub(crate) const PINGS_HEADER: &str = "host_send,host_recv,device,segment";
/// The extra `joints.csv` columns of a recording from a controller with a
/// clock (UR): its timestamp and the host's arrival time, s.
pub(crate) const JOINT_CLOCK_COLUMNS: [&str; 2] = ["t_robot", "t_arrival"];

/// What [`remap_joint_times`] did.
#[derive(Debug, Clone, PartialEq)]
pub enum JointClock {
    /// Joint times recomputed from the controller's clock, with the fit of
    /// each clock segment.
    Mapped(Vec<(u32, RobotClockFit)>),
    /// Joint times left at the arrival times, and why.
    Kept(String),
}

/// What [`repair`] did.
#[derive(Debug, Default, Clone, PartialEq)]
pub struct RepairReport {
    /// Files whose cut last line was removed, with that line's number.
    pub truncated: Vec<(PathBuf, usize)>,
    /// The clock fit of each segment, when `imu.csv` times were recomputed.
    pub clock: Vec<(u32, ClockFit)>,
    /// IMU rows whose segment had no usable echo (left as written).
    pub unmapped_rows: usize,
    /// The joint times' clock mapping, when `joints.csv` has the
    /// controller's timestamps.
    pub joint_clock: Option<JointClock>,
}

/// Removes a cut last line from every CSV of the session, then recomputes
/// the IMU times from the ping log when the session has one.
pub fn repair(dir: &Path) -> Result<RepairReport, SessionError> {
    if !dir.is_dir() {
        return Err(SessionError::io(
            dir,
            std::io::Error::new(std::io::ErrorKind::NotFound, "no such session directory"),
        ));
    }
    let mut report = RepairReport::default();
    let mut names: Vec<String> = [files::JOINTS, files::IMU, files::TRACKER, PINGS]
        .map(String::from)
        .to_vec();
    names.extend(extra_imu_files(dir)?.into_iter().map(|(_, n)| n));
    names.extend((1..).map(pings_file).take_while(|n| dir.join(n).is_file()));
    for name in &names {
        let path = dir.join(name);
        if path.is_file() {
            if let Some(line) = drop_cut_line(&path)? {
                report.truncated.push((path, line));
            }
        }
    }
    if dir.join(PINGS).is_file() {
        let (clock, unmapped) = remap_imu_times(dir)?;
        report.clock = clock;
        report.unmapped_rows = unmapped;
    }
    if dir.join(files::JOINTS).is_file() {
        report.joint_clock = remap_joint_times(dir)?;
        if let Some(clock) = &report.joint_clock {
            write_controller_clock(dir, clock)?;
        }
    }
    Ok(report)
}

/// Drops the last line of `path` if it does not end in a newline or has
/// fewer fields than the header. Returns its line number if dropped.
fn drop_cut_line(path: &Path) -> Result<Option<usize>, SessionError> {
    let text = robimu_model::text::read_to_string(path).map_err(|e| SessionError::io(path, e))?;
    let Some(header) = text.lines().next() else {
        return Ok(None);
    };
    let width = header.split(',').count();
    let body_end = if text.ends_with('\n') {
        // Complete last line: check its width.
        let trimmed = &text[..text.len() - 1];
        let start = trimmed.rfind('\n').map_or(0, |i| i + 1);
        let last = &trimmed[start..];
        if start == 0 || last.starts_with('#') || last.split(',').count() >= width {
            return Ok(None);
        }
        start
    } else {
        text.rfind('\n').map_or(0, |i| i + 1)
    };
    if body_end == 0 {
        // Only a cut header: nothing to keep.
        return Ok(None);
    }
    let line_number = text[..body_end].lines().count() + 1;
    write_atomically(path, &text.as_bytes()[..body_end])?;
    Ok(Some(line_number))
}

/// Reads `pings.csv`: echoes by segment.
pub(crate) fn read_pings(path: &Path) -> Result<BTreeMap<u32, Vec<Echo>>, SessionError> {
    let text = robimu_model::text::read_to_string(path).map_err(|e| SessionError::io(path, e))?;
    let mut out: BTreeMap<u32, Vec<Echo>> = BTreeMap::new();
    for (i, line) in text.lines().enumerate().skip(1) {
        if line.starts_with('#') || line.trim().is_empty() {
            continue;
        }
        let bad = |e: String| SessionError::io(path, bad_data(format!("line {}: {e}", i + 1)));
        let fields: Vec<&str> = line.split(',').collect();
        if fields.len() < 4 {
            return Err(bad(format!("expected {PINGS_HEADER}")));
        }
        let times: Vec<f64> = fields[..3]
            .iter()
            .map(|f| time_field(f))
            .collect::<Result<_, _>>()
            .map_err(bad)?;
        let segment = segment_field(fields[3]).map_err(bad)?;
        out.entry(segment).or_default().push(Echo {
            host_send: times[0],
            host_recv: times[1],
            device: times[2],
        });
    }
    Ok(out)
}

/// The `imu<j>.csv` files of `dir`, with j (docs/model.md §9).
fn extra_imu_files(dir: &Path) -> Result<Vec<(usize, String)>, SessionError> {
    let listing = std::fs::read_dir(dir).map_err(|e| SessionError::io(dir, e))?;
    let names: Vec<String> = listing
        .filter_map(|e| e.ok()?.file_name().into_string().ok())
        .collect();
    Ok(files::extra_imu_indices(names.iter().map(String::as_str))
        .into_iter()
        .map(|j| (j, files::imu_csv(j)))
        .collect())
}

/// Rewrites the `t` column of `imu.csv` from `t_device` and `segment` with
/// each segment's final clock fit (and of every `imu<j>.csv`,
/// [`remap_all_imu_times`]). Returns IMU 0's fits and the number of rows
/// left as they were (segment without echoes), all IMUs counted.
pub fn remap_imu_times(dir: &Path) -> Result<(Vec<(u32, ClockFit)>, usize), SessionError> {
    let all = remap_all_imu_times(dir)?;
    let unmapped = all.iter().map(|(_, _, u)| u).sum();
    let first = all.into_iter().find(|(j, _, _)| *j == 0).map(|(_, f, _)| f);
    Ok((first.unwrap_or_default(), unmapped))
}

/// What [`remap_all_imu_times`] did to one IMU's file: `(j, the clock
/// fits of its board by segment, rows left as they were)`.
pub(crate) type ImuRemap = (usize, Vec<(u32, ClockFit)>, usize);

/// [`remap_imu_times`] for each IMU of the session (docs/model.md §9),
/// each from its board's ping log: `(j, fits, rows left as they were)`,
/// IMU 0 first.
pub(crate) fn remap_all_imu_times(dir: &Path) -> Result<Vec<ImuRemap>, SessionError> {
    let meta_path = dir.join(files::META);
    let meta = if meta_path.is_file() {
        Some(SessionMeta::read(&meta_path)?)
    } else {
        None
    };
    let pings_of = |j: usize| -> String {
        let table = match (&meta, j) {
            (Some(m), 0) => m.imu.as_ref(),
            (Some(m), j) => m.imu_tables.get(&j),
            (None, _) => None,
        };
        table
            .and_then(|t| t.get("pings"))
            .and_then(|v| v.as_str())
            .unwrap_or(PINGS)
            .to_string()
    };
    let mut imus = vec![(0, files::IMU.to_string())];
    imus.extend(extra_imu_files(dir)?);
    let mut fits_by_log: BTreeMap<String, BTreeMap<u32, ClockFit>> = BTreeMap::new();
    let mut out = Vec::with_capacity(imus.len());
    for (j, file) in imus {
        let log = pings_of(j);
        if !fits_by_log.contains_key(&log) {
            let path = dir.join(&log);
            if !path.is_file() {
                continue;
            }
            let fits = read_pings(&path)?
                .iter()
                .filter_map(|(s, e)| {
                    ClockFit::fit(e)
                        .or_else(|| e.first().map(ClockFit::offset_only))
                        .map(|f| (*s, f))
                })
                .collect();
            fits_by_log.insert(log.clone(), fits);
        }
        let fits = &fits_by_log[&log];
        let path = dir.join(&file);
        if !path.is_file() {
            continue;
        }
        let unmapped = remap_file(&path, fits)?;
        out.push((j, fits.iter().map(|(s, f)| (*s, *f)).collect(), unmapped));
    }
    Ok(out)
}

/// Rewrites `path`'s `t` column with `fits`; the rows left as they were.
fn remap_file(path: &Path, fits: &BTreeMap<u32, ClockFit>) -> Result<usize, SessionError> {
    let path = path.to_path_buf();
    let text = robimu_model::text::read_to_string(&path).map_err(|e| SessionError::io(&path, e))?;
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default();
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let (Some(td), Some(sg)) = (
        cols.iter().position(|c| *c == "t_device"),
        cols.iter().position(|c| *c == "segment"),
    ) else {
        return Ok(0);
    };
    let mut out = String::with_capacity(text.len());
    out.push_str(header);
    out.push('\n');
    let mut unmapped = 0;
    for (i, line) in lines.enumerate() {
        let fields: Vec<&str> = line.split(',').collect();
        let given = |k: usize| fields.get(k).map(|f| f.trim()).filter(|f| !f.is_empty());
        let mut mapped = None;
        if let (Some(device), Some(segment), false) = (given(td), given(sg), line.starts_with('#'))
        {
            let bad = |e: String| SessionError::io(&path, bad_data(format!("line {}: {e}", i + 2)));
            let device = time_field(device).map_err(bad)?;
            let segment = segment_field(segment).map_err(bad)?;
            mapped = fits.get(&segment).map(|fit| fit.to_session(device));
        }
        match mapped {
            Some(t) if !line.starts_with('#') => {
                out.push_str(&format!("{t:?}"));
                for f in &fields[1..] {
                    out.push(',');
                    out.push_str(f);
                }
            }
            _ => {
                unmapped += usize::from(!line.starts_with('#'));
                out.push_str(line);
            }
        }
        out.push('\n');
    }
    write_atomically(&path, out.as_bytes())?;
    Ok(unmapped)
}

/// Rewrites the `t` column of `joints.csv` from its `t_robot` column with
/// the controller clock's fit through `(t_robot, t_arrival)`
/// ([`robot_clock::remap`]); when that is refused, `t` is set back to
/// `t_arrival`. `None` (nothing changed) without those columns (AUBO).
pub(crate) fn remap_joint_times(dir: &Path) -> Result<Option<JointClock>, SessionError> {
    let path = dir.join(files::JOINTS);
    let text = robimu_model::text::read_to_string(&path).map_err(|e| SessionError::io(&path, e))?;
    let mut lines = text.lines();
    let header = lines.next().unwrap_or_default();
    let cols: Vec<&str> = header.split(',').map(str::trim).collect();
    let [Some(tr), Some(ta)] = JOINT_CLOCK_COLUMNS.map(|c| cols.iter().position(|h| *h == c))
    else {
        return Ok(None);
    };
    let is_row = |l: &&str| !l.starts_with('#') && !l.trim().is_empty();
    // each row's (t_robot, t_arrival), range-checked as every time of the
    // recorder's files ([`time_field`]); a t_robot the recorder left NaN
    // (a sample without the controller's timestamp) stays NaN
    let mut samples: Vec<(f64, f64)> = Vec::new();
    for (i, line) in lines.clone().enumerate() {
        if !is_row(&line) {
            continue;
        }
        let bad = |e: String| SessionError::io(&path, bad_data(format!("line {}: {e}", i + 2)));
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let field = |k: usize, name: &str| {
            fields
                .get(k)
                .copied()
                .ok_or_else(|| bad(format!("no {name} field (expected {})", header.trim())))
        };
        let robot = field(tr, "t_robot")?;
        let robot = if robot.is_empty() || robot.eq_ignore_ascii_case("nan") {
            f64::NAN
        } else {
            time_field(robot).map_err(|e| bad(format!("t_robot: {e}")))?
        };
        let arrival =
            time_field(field(ta, "t_arrival")?).map_err(|e| bad(format!("t_arrival: {e}")))?;
        samples.push((robot, arrival));
    }
    let (clock, times) = match robot_clock::remap(&samples) {
        Ok(r) => (JointClock::Mapped(r.fits), r.times),
        Err(why) => (JointClock::Kept(why), samples.iter().map(|s| s.1).collect()),
    };
    let mut out = String::with_capacity(text.len());
    out.push_str(header);
    out.push('\n');
    let mut times = times.iter();
    for line in lines {
        match Some(line).filter(is_row).and_then(|_| times.next()) {
            Some(t) => {
                out.push_str(&format!("{t:?}"));
                out.push_str(line.find(',').map_or("", |k| &line[k..]));
            }
            None => out.push_str(line),
        }
        out.push('\n');
    }
    write_atomically(&path, out.as_bytes())?;
    Ok(Some(clock))
}

/// Keeps the joint clock mapping in session.toml's `[controller]` table:
/// `clock = [{segment, offset_s, drift_ppm, jitter_us, windows_used,
/// windows, samples}, …]`, or `clock_note` when the arrival times were kept.
pub(crate) fn write_controller_clock(dir: &Path, clock: &JointClock) -> Result<(), SessionError> {
    update_meta(dir, |meta| {
        let table = meta.controller.get_or_insert_with(toml::Table::new);
        table.remove("clock");
        table.remove("clock_note");
        match clock {
            JointClock::Mapped(fits) => {
                let fits: Vec<toml::Value> = fits
                    .iter()
                    .map(|(segment, f)| {
                        clock_row(
                            *segment,
                            f.offset,
                            f.drift_ppm(),
                            [
                                ("jitter_us", (f.jitter_rms * 1e6).into()),
                                ("windows_used", (f.windows_used as i64).into()),
                                ("windows", (f.windows as i64).into()),
                                ("samples", (f.samples as i64).into()),
                            ],
                        )
                    })
                    .collect();
                table.insert("clock".into(), fits.into());
            }
            JointClock::Kept(why) => {
                table.insert(
                    "clock_note".into(),
                    format!("joint times are host arrival times: {why}").into(),
                );
            }
        }
    })
}

/// Reads session.toml in `dir`, lets `edit` change it, writes it back.
pub(super) fn update_meta(
    dir: &Path,
    edit: impl FnOnce(&mut SessionMeta),
) -> Result<(), SessionError> {
    let path = dir.join(files::META);
    let mut meta = SessionMeta::read(&path)?;
    edit(&mut meta);
    std::fs::write(&path, meta.to_toml()).map_err(|e| SessionError::io(&path, e))
}

/// One clock segment's row in session.toml: `segment`, `offset_s`,
/// `drift_ppm`, then the fit's own figures.
pub(super) fn clock_row<const N: usize>(
    segment: u32,
    offset_s: f64,
    drift_ppm: f64,
    extra: [(&str, toml::Value); N],
) -> toml::Value {
    let mut t = toml::Table::new();
    t.insert("segment".into(), i64::from(segment).into());
    t.insert("offset_s".into(), offset_s.into());
    t.insert("drift_ppm".into(), drift_ppm.into());
    for (k, v) in extra {
        t.insert(k.into(), v);
    }
    t.into()
}

/// Writes `bytes` to a temporary file beside `path`, then renames it over
/// `path`: a crash leaves either the old or the new file, never half.
fn write_atomically(path: &Path, bytes: &[u8]) -> Result<(), SessionError> {
    let tmp = path.with_extension("csv.tmp");
    let mut f = std::fs::File::create(&tmp).map_err(|e| SessionError::io(&tmp, e))?;
    f.write_all(bytes).map_err(|e| SessionError::io(&tmp, e))?;
    f.sync_all().map_err(|e| SessionError::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| SessionError::io(path, e))
}

/// The largest magnitude of a time (s) in the recorder's files: 10¹⁰ s
/// (three centuries; epoch times are 1.7·10⁹ s).
const MAX_TIME: f64 = 1e10;

/// A time field (s): a finite number within ±[`MAX_TIME`].
fn time_field(text: &str) -> Result<f64, String> {
    let v: f64 = text
        .trim()
        .parse()
        .map_err(|e| format!("time {:?}: {e}", text.trim()))?;
    if !(v.is_finite() && v.abs() <= MAX_TIME) {
        return Err(format!(
            "time {:?} is not a finite number within ±{MAX_TIME:e} s",
            text.trim()
        ));
    }
    Ok(v)
}

/// A clock segment: a whole number from 0 (`3.0` is read as 3).
fn segment_field(text: &str) -> Result<u32, String> {
    let t = text.trim();
    let v: f64 = t
        .parse()
        .map_err(|_| format!("segment {t:?} is not a number"))?;
    if !(v.is_finite() && v >= 0.0 && v.fract() == 0.0 && v <= f64::from(u32::MAX)) {
        return Err(format!(
            "segment {t:?} is not a whole number from 0 (the recorder counts clock segments 0, 1, 2, …)"
        ));
    }
    Ok(v as u32)
}

fn bad_data(msg: String) -> std::io::Error {
    std::io::Error::new(std::io::ErrorKind::InvalidData, msg)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cut_last_lines_are_dropped_and_whole_files_kept() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("joints.csv");
        std::fs::write(&p, "t,q1,q2\n0.0,1,2\n0.1,1,2\n0.2,1").unwrap();
        assert_eq!(drop_cut_line(&p).unwrap(), Some(4));
        assert_eq!(
            std::fs::read_to_string(&p).unwrap(),
            "t,q1,q2\n0.0,1,2\n0.1,1,2\n"
        );
        assert_eq!(drop_cut_line(&p).unwrap(), None);
        std::fs::write(&p, "t,q1,q2\n0.0,1,2\n0.1,\n").unwrap();
        assert_eq!(drop_cut_line(&p).unwrap(), Some(3));
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "t,q1,q2\n0.0,1,2\n");
    }

    /// A UR `joints.csv`: `t` is recomputed from `t_robot` (a controller
    /// 1000 s ahead, 50 ppm fast; arrivals 0.2–2.2 ms late), comments and
    /// the other columns kept, the fit kept in session.toml; a second
    /// repair gives the same bytes. An AUBO file (no clock columns) is left
    /// alone; a restart within the old clock's range keeps arrival times.
    #[test]
    fn joint_times_are_recomputed_from_the_controller_clock() {
        let dir = tempfile::tempdir().unwrap();
        let meta = dir.path().join(files::META);
        std::fs::write(&meta, SessionMeta::new("aubo_i5").to_toml()).unwrap();
        let joints = dir.path().join(files::JOINTS);
        let mut text = String::from("t,q1,t_robot,t_arrival\n# a comment\n");
        let mut truth = Vec::new();
        for k in 0..1250 {
            let t = 0.5 + k as f64 * 0.008;
            let late = 2e-4 + 2e-3 * ((k * 37 % 101) as f64 / 100.0);
            let robot = 1000.0 + (1.0 + 50e-6) * t;
            text.push_str(&format!("{:?},{k},{robot:?},{:?}\n", t + late, t + late));
            truth.push(t + 2e-4);
        }
        std::fs::write(&joints, &text).unwrap();
        let report = repair(dir.path()).unwrap();
        let Some(JointClock::Mapped(fits)) = &report.joint_clock else {
            panic!("{:?}", report.joint_clock);
        };
        assert_eq!(fits.len(), 1);
        assert!((fits[0].1.drift_ppm() - 50.0).abs() < 5.0, "{fits:?}");
        let after = std::fs::read_to_string(&joints).unwrap();
        assert!(after.starts_with("t,q1,t_robot,t_arrival\n# a comment\n"));
        for (line, want) in after.lines().skip(2).zip(&truth) {
            let t: f64 = line.split(',').next().unwrap().parse().unwrap();
            assert!((t - want).abs() < 4e-5, "{line} vs {want}");
        }
        let m = SessionMeta::read(&meta).unwrap();
        let clock = m.controller.unwrap()["clock"].as_array().unwrap().clone();
        assert_eq!(clock.len(), 1);
        assert!((clock[0]["drift_ppm"].as_float().unwrap() - 50.0).abs() < 5.0);
        repair(dir.path()).unwrap();
        assert_eq!(std::fs::read_to_string(&joints).unwrap(), after);

        // AUBO: untouched
        let aubo = "t,q1\n0.1,1\n0.2,2\n";
        std::fs::write(&joints, aubo).unwrap();
        assert_eq!(repair(dir.path()).unwrap().joint_clock, None);
        assert_eq!(std::fs::read_to_string(&joints).unwrap(), aubo);

        // restarted 1 ms after its old clock's last reading: kept
        let restart = "t,q1,t_robot,t_arrival\n9,0,10.0,1.0\n9,0,11.0,2.0\n9,0,12.0,3.0\n9,0,13.0,4.0\n9,0,0.0,4.001\n9,0,0.4,4.0012\n";
        std::fs::write(&joints, restart).unwrap();
        let Some(JointClock::Kept(why)) = repair(dir.path()).unwrap().joint_clock else {
            panic!("not kept");
        };
        assert!(why.contains("before the one it follows"), "{why}");
        let ts: Vec<String> = std::fs::read_to_string(&joints)
            .unwrap()
            .lines()
            .skip(1)
            .map(|l| l.split(',').next().unwrap().to_string())
            .collect();
        assert_eq!(ts, ["1.0", "2.0", "3.0", "4.0", "4.001", "4.0012"]);
        let m = SessionMeta::read(&meta).unwrap();
        let c = m.controller.unwrap();
        assert!(c.get("clock").is_none());
        assert!(c["clock_note"].as_str().unwrap().contains("arrival times"));
    }

    #[test]
    fn imu_times_are_recomputed_from_the_ping_log() {
        let dir = tempfile::tempdir().unwrap();
        // Device clock 3 s ahead and 100 ppm fast; segment 1 restarted at 0
        // when the session clock read 10 s.
        let dev = |seg: u32, t: f64| {
            if seg == 0 {
                3.0 + (1.0 + 1e-4) * t
            } else {
                (1.0 + 1e-4) * (t - 10.0)
            }
        };
        let mut pings = format!("{PINGS_HEADER}\n");
        for k in 0..75 {
            let t = 0.2 * k as f64;
            let seg = u32::from(t >= 10.0);
            pings.push_str(&format!(
                "{},{},{},{seg}\n",
                t - 1e-4,
                t + 1e-4,
                dev(seg, t)
            ));
        }
        std::fs::write(dir.path().join(PINGS), pings).unwrap();
        let mut imu = String::from("t,ax,ay,az,gx,gy,gz,t_device,segment,seq,temp_c\n");
        for (k, t) in [1.0, 2.5, 9.9, 10.5, 12.0].iter().enumerate() {
            let seg = u32::from(*t >= 10.0);
            imu.push_str(&format!(
                "0,1,2,3,4,5,6,{:?},{seg},{k},{}\n",
                dev(seg, *t),
                20 + k
            ));
        }
        std::fs::write(dir.path().join("imu.csv"), imu).unwrap();
        let report = repair(dir.path()).unwrap();
        assert_eq!(report.clock.len(), 2);
        assert_eq!(report.unmapped_rows, 0);
        let text = robimu_model::text::read_to_string(dir.path().join("imu.csv")).unwrap();
        let ts: Vec<f64> = text
            .lines()
            .skip(1)
            .map(|l| l.split(',').next().unwrap().parse().unwrap())
            .collect();
        for (t, want) in ts.iter().zip([1.0, 2.5, 9.9, 10.5, 12.0]) {
            assert!((t - want).abs() < 1e-6, "{t} vs {want}");
        }
        // the extra columns (here the temperature) are kept as written
        assert!(text.starts_with("t,ax,ay,az,gx,gy,gz,t_device,segment,seq,temp_c\n"));
        let temps: Vec<&str> = text
            .lines()
            .skip(1)
            .map(|l| l.rsplit(',').next().unwrap())
            .collect();
        assert_eq!(temps, ["20", "21", "22", "23", "24"]);
        assert!((report.clock[0].1.drift_ppm() - 100.0).abs() < 1e-3);
    }

    /// Issue 41: numbers a recorder cannot have written are refused, naming
    /// the file and line, before any clock fit.
    #[test]
    fn impossible_times_and_segments_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let good = format!("{PINGS_HEADER}\n0.1,0.2,3.1,0\n0.3,0.4,3.3,0\n");
        for (row, want) in [
            (
                "NaN,0.6,3.5,0",
                "line 4: time \"NaN\" is not a finite number",
            ),
            (
                "0.5,inf,3.5,0",
                "line 4: time \"inf\" is not a finite number",
            ),
            (
                "0.5,0.6,1e309,0",
                "line 4: time \"1e309\" is not a finite number",
            ),
            (
                "0.5,0.6,3.5,1.5",
                "line 4: segment \"1.5\" is not a whole number",
            ),
            (
                "0.5,0.6,3.5,-1",
                "line 4: segment \"-1\" is not a whole number",
            ),
        ] {
            let path = dir.path().join(PINGS);
            std::fs::write(&path, format!("{good}{row}\n")).unwrap();
            let e = read_pings(&path).unwrap_err().to_string();
            assert!(e.contains(PINGS) && e.contains(want), "{row}: {e}");
        }
        // imu.csv's device time and segment, with a good ping log.
        std::fs::write(dir.path().join(PINGS), &good).unwrap();
        for (row, want) in [
            (
                "0,1,2,3,4,5,6,nan,0",
                "line 3: time \"nan\" is not a finite number",
            ),
            (
                "0,1,2,3,4,5,6,3.2,0.5",
                "line 3: segment \"0.5\" is not a whole number",
            ),
        ] {
            let imu = format!("t,ax,ay,az,gx,gy,gz,t_device,segment\n0,1,2,3,4,5,6,3.1,0\n{row}\n");
            std::fs::write(dir.path().join("imu.csv"), imu).unwrap();
            let e = repair(dir.path()).unwrap_err().to_string();
            assert!(e.contains("imu.csv") && e.contains(want), "{row}: {e}");
        }
    }

    /// Issue 41: joints.csv's controller clock columns are range-checked as
    /// the other times (finite, within ±1e10 s), naming file and line,
    /// before any fit — 1e308 or inf went into the clock fit, a t_arrival of
    /// 1e308 became a joint time. A NaN t_robot (a sample the controller
    /// did not stamp, as the recorder writes it) is still taken as missing.
    #[test]
    fn impossible_controller_clock_times_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(
            dir.path().join(files::META),
            SessionMeta::new("ur5e").to_toml(),
        )
        .unwrap();
        let joints = dir.path().join(files::JOINTS);
        let good = "t,q1,t_robot,t_arrival\n0.1,0,1000.1,0.1\n0.2,0,1000.2,0.2\n";
        // the row under test, then a whole last row (a short last row is a
        // cut line, which repair drops)
        let last = "0.4,0,1000.4,0.4\n";
        for (row, want) in [
            (
                "0.3,0,1e308,0.3",
                "line 4: t_robot: time \"1e308\" is not a finite number within ±1e10 s",
            ),
            (
                "0.3,0,-inf,0.3",
                "line 4: t_robot: time \"-inf\" is not a finite number",
            ),
            (
                "0.3,0,1000.3,1e309",
                "line 4: t_arrival: time \"1e309\" is not a finite number",
            ),
            (
                "0.3,0,1000.3,NaN",
                "line 4: t_arrival: time \"NaN\" is not a finite number",
            ),
            (
                "0.3,0,1000.3,x",
                "line 4: t_arrival: time \"x\": invalid float literal",
            ),
            (
                "0.3,0,1000.3",
                "line 4: no t_arrival field (expected t,q1,t_robot,t_arrival)",
            ),
        ] {
            std::fs::write(&joints, format!("{good}{row}\n{last}")).unwrap();
            let e = repair(dir.path()).unwrap_err().to_string();
            assert!(e.contains("joints.csv") && e.contains(want), "{row}: {e}");
            // refused before anything is rewritten
            assert_eq!(
                std::fs::read_to_string(&joints).unwrap(),
                format!("{good}{row}\n{last}")
            );
        }
        // unstamped samples: the arrival times are kept
        std::fs::write(&joints, format!("{good}0.3,0,NaN,0.3\n{last}")).unwrap();
        let Some(JointClock::Kept(why)) = repair(dir.path()).unwrap().joint_clock else {
            panic!("not kept");
        };
        assert!(
            why.contains("joint sample 3 has no controller timestamp"),
            "{why}"
        );
    }
}
