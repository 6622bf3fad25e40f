//! The table of `robimu check` (and of the check at the start of
//! `calibrate`): one row per finding, worst first, what to do under it.

use std::fmt;

use robimu_workflows::check::{CheckReport, Severity};

/// The findings as a table; `min` leaves out the less severe ones.
pub struct CheckTable<'a> {
    /// The findings.
    pub report: &'a CheckReport,
    /// The least severity shown.
    pub min: Severity,
}

impl fmt::Display for CheckTable<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = self.report;
        let count = |s| r.of(s).count();
        writeln!(
            f,
            "check: {} fatal, {} warning(s), {} info",
            count(Severity::Fatal),
            count(Severity::Warning),
            count(Severity::Info)
        )?;
        let mut rows: Vec<_> = r
            .findings
            .iter()
            .filter(|x| x.severity >= self.min)
            .collect();
        if rows.is_empty() {
            return Ok(());
        }
        rows.sort_by_key(|x| std::cmp::Reverse(x.severity));
        writeln!(f, "{:<8} {:<16} finding", "severity", "kind")?;
        for x in rows {
            writeln!(f, "{:<8} {:<16} {}", x.severity, x.kind, x.message)?;
            if !x.action.is_empty() {
                writeln!(f, "{:<25} -> {}", "", x.action)?;
            }
        }
        Ok(())
    }
}
