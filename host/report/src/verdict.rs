//! The verdict as text (the top of `calibrate`'s output) and as the HTML
//! report's first block: one line per check, then `trust: … — reasons`.

use std::fmt;

use robimu_session::result::VerdictRecord;

/// The verdict's lines and its trust line.
pub struct VerdictText<'a>(pub &'a VerdictRecord);

/// The one line `trust: good`, or `trust: doubtful — reason; reason`.
pub fn trust_line(v: &VerdictRecord) -> String {
    if v.reasons.is_empty() {
        format!("trust: {}", v.trust)
    } else {
        format!("trust: {} — {}", v.trust, v.reasons.join("; "))
    }
}

impl fmt::Display for VerdictText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "verdict:")?;
        for c in &self.0.checks {
            let mark = if c.ok { "ok" } else { "FAIL" };
            writeln!(f, "  {mark:<4} {:<13} {}", c.topic, c.text)?;
        }
        writeln!(f, "{}", trust_line(self.0))?;
        for step in &self.0.next_steps {
            writeln!(f, "  next: {step}")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robimu_session::result::{Trust, VerdictCheck};

    #[test]
    fn trust_line_names_the_reasons() {
        let mut v = VerdictRecord {
            trust: Trust::Good,
            reasons: vec![],
            checks: vec![VerdictCheck {
                topic: "converged".into(),
                ok: true,
                text: "converged".into(),
            }],
            next_steps: vec![],
        };
        assert_eq!(trust_line(&v), "trust: good");
        v.trust = Trust::Doubtful;
        v.reasons = vec!["residuals: not white".into()];
        let text = VerdictText(&v).to_string();
        assert!(text.contains("  ok   converged"), "{text}");
        assert!(
            text.ends_with("trust: doubtful — residuals: not white\n"),
            "{text}"
        );
    }
}
