//! The subcommands, one module each; each is a clap struct whose `run`
//! calls the library.

pub mod allan;
pub mod calibrate;
pub mod calibrate_batch;
pub mod check;
pub mod correct;
pub mod demo;
pub mod diagnose;
pub mod export;
pub mod identifiability;
pub mod import;
pub mod montecarlo;
pub mod noise;
pub mod plan;
pub mod record;
pub mod repair;
pub mod report;
pub mod robots;
pub mod simulate;
pub mod validate;

/// What `robimu` can do (each command's help is its struct's doc comment).
#[derive(Debug, clap::Subcommand)]
pub enum Command {
    Demo(demo::DemoCmd),
    Plan(plan::PlanCmd),
    Record(record::RecordCmd),
    Repair(repair::RepairCmd),
    Import(import::ImportCmd),
    Simulate(simulate::SimulateCmd),
    Calibrate(calibrate::CalibrateCmd),
    Check(check::CheckCmd),
    CalibrateBatch(calibrate_batch::CalibrateBatchCmd),
    Diagnose(diagnose::DiagnoseCmd),
    Validate(validate::ValidateCmd),
    Report(report::ReportCmd),
    Export(export::ExportCmd),
    Correct(correct::CorrectCmd),
    Identifiability(identifiability::IdentifiabilityCmd),
    Robots(robots::RobotsCmd),
    #[command(name = "montecarlo")]
    MonteCarlo(montecarlo::MonteCarloCmd),
    Noise(noise::NoiseCmd),
    Allan(allan::AllanCmd),
}

impl Command {
    /// Run the subcommand.
    pub fn run(self) -> anyhow::Result<()> {
        match self {
            Command::Demo(c) => c.run(),
            Command::Simulate(c) => c.run(),
            Command::Calibrate(c) => c.run(),
            Command::Check(c) => c.run(),
            Command::CalibrateBatch(c) => c.run(),
            Command::MonteCarlo(c) => c.run(),
            Command::Noise(c) => c.run(),
            Command::Allan(c) => c.run(),
            Command::Record(c) => c.run(),
            Command::Repair(c) => c.run(),
            Command::Export(c) => c.run(),
            Command::Correct(c) => c.run(),
            Command::Import(c) => c.run(),
            Command::Validate(c) => c.run(),
            Command::Report(c) => c.run(),
            Command::Diagnose(c) => c.run(),
            Command::Plan(c) => c.run(),
            Command::Identifiability(c) => c.run(),
            Command::Robots(c) => c.run(),
        }
    }
}

/// `error: …` and one `  caused by: …` line per cause, leaving out causes
/// whose text the line before already contains.
pub fn error_report(e: &anyhow::Error) -> String {
    let mut text = format!("error: {e}\n");
    let mut previous = e.to_string();
    for cause in e.chain().skip(1) {
        let line = cause.to_string();
        if !previous.contains(&line) {
            text.push_str(&format!("  caused by: {line}\n"));
        }
        previous = line;
    }
    text
}
