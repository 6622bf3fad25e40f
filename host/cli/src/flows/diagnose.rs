//! A diagnosis as the program shows it (`robimu diagnose`, `robimu demo`):
//! the library's pipeline ([`robimu_workflows::diagnose_session`]) with a
//! progress line, the summary, diagnosis.json and the residual figures.

use std::io::Write;
use std::path::Path;

use robimu_report::diagnosis::DiagnosisSummary;
use robimu_report::diagnosis_figures::{residuals_plot, spectra_plot};
use robimu_workflows::diagnose::Diagnosis;
use robimu_workflows::{diagnose_session, DiagnoseSettings, Diagnosed};

use crate::input::Progress;

/// Diagnoses the session in `dir`, prints the summary and writes
/// diagnosis.json and the figures into `settings.out`.
pub fn run(dir: &Path, settings: &DiagnoseSettings) -> anyhow::Result<Diagnosis> {
    let progress = Progress::start("fitting the baseline model");
    let d = diagnose_session(dir, settings, |m| progress.set_message(m.to_string()));
    progress.finish();
    let d = d?;
    let out_dir = &settings.out;
    // the two figures on their own threads while the summary and the
    // JSON are written (each is independent of the others)
    let (written, residuals, spectra) = std::thread::scope(|s| {
        let residuals =
            s.spawn(|| residuals_plot(&out_dir.join("residuals"), &d.data, &d.diagnosis));
        let spectra =
            s.spawn(|| spectra_plot(&out_dir.join("residual_spectra"), &d.data, &d.diagnosis));
        let written = write_summary(out_dir, &d);
        (
            written,
            residuals.join().expect("residual plot panicked"),
            spectra.join().expect("spectra plot panicked"),
        )
    });
    written?;
    let mut out = std::io::stdout().lock();
    for p in residuals?.into_iter().chain(spectra?) {
        writeln!(out, "wrote {}", p.display())?;
    }
    Ok(d.diagnosis)
}

/// Print the summary and write DIR/diagnosis.json.
fn write_summary(out_dir: &Path, d: &Diagnosed) -> anyhow::Result<()> {
    let mut out = std::io::stdout().lock();
    write!(out, "{}", DiagnosisSummary(&d.diagnosis))?;
    let path = d.write_json(out_dir)?;
    writeln!(out, "wrote {}", path.display())?;
    Ok(())
}
