//! Display units: files hold SI (docs/model.md §5), people read millimetres,
//! degrees (the paper's Table II) and milliseconds (the time offset τ).

use std::f64::consts::PI;

/// The unit a parameter is shown in.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DisplayUnit {
    /// `m` shown as mm.
    Millimetre,
    /// `rad` shown as degrees.
    Degree,
    /// `rad/s` shown as °/s.
    DegreePerSecond,
    /// `s` shown as ms (τ and the effects' delays are milliseconds).
    Millisecond,
    /// Any other unit, shown as it is in the file.
    Si(String),
}

impl DisplayUnit {
    /// The display unit for a file's unit string.
    pub fn for_si(unit: &str) -> Self {
        match unit {
            "m" => Self::Millimetre,
            "rad" => Self::Degree,
            "rad/s" => Self::DegreePerSecond,
            "s" => Self::Millisecond,
            other => Self::Si(other.to_string()),
        }
    }

    /// Display value per SI value.
    pub fn scale(&self) -> f64 {
        match self {
            Self::Millimetre | Self::Millisecond => 1e3,
            Self::Degree | Self::DegreePerSecond => 180.0 / PI,
            Self::Si(_) => 1.0,
        }
    }

    /// An SI value in this unit.
    pub fn show(&self, si: f64) -> f64 {
        si * self.scale()
    }

    /// The unit's symbol.
    pub fn symbol(&self) -> &str {
        match self {
            Self::Millimetre => "mm",
            Self::Degree => "deg",
            Self::DegreePerSecond => "deg/s",
            Self::Millisecond => "ms",
            Self::Si(s) => s,
        }
    }

    /// Whether values are angles (differences wrap at ±180°).
    pub fn is_angle(&self) -> bool {
        matches!(self, Self::Degree)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversions() {
        assert_eq!(DisplayUnit::for_si("m").show(0.0252), 25.2);
        assert!((DisplayUnit::for_si("rad").show(PI) - 180.0).abs() < 1e-12);
        let dps = DisplayUnit::for_si("rad/s");
        assert!((dps.show(5.0 * PI / 180.0) - 5.0).abs() < 1e-12);
        assert_eq!(dps.symbol(), "deg/s");
        let ms = DisplayUnit::for_si("s");
        assert_eq!((ms.show(0.0125), ms.symbol()), (12.5, "ms"));
        let g = DisplayUnit::for_si("m/s^2");
        assert_eq!((g.show(9.81), g.symbol()), (9.81, "m/s^2"));
        assert!(DisplayUnit::for_si("rad").is_angle() && !dps.is_angle());
    }
}
