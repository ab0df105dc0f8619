//! The A4988's microstep modes and the MS1–MS3 levels that select them.

use std::fmt;
use std::str::FromStr;

use crate::TurntableError;

/// A4988 microstep mode, selected with the MS1, MS2, MS3 pins.
///
/// | mode | MS1 | MS2 | MS3 | microsteps per full step |
/// |---|---|---|---|---|
/// | full | L | L | L | 1 |
/// | half | H | L | L | 2 |
/// | quarter | L | H | L | 4 |
/// | eighth | H | H | L | 8 |
/// | sixteenth | H | H | H | 16 |
///
/// (A4988 datasheet, Table 1 "Microstepping Resolution Truth Table".) A
/// 1.8° motor at quarter stepping turns 0.45° per microstep, the thesis's
/// setting.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Microstep {
    /// Full steps.
    Full,
    /// Half steps.
    Half,
    /// Quarter steps (the default).
    #[default]
    Quarter,
    /// Eighth steps.
    Eighth,
    /// Sixteenth steps.
    Sixteenth,
}

impl Microstep {
    /// Every mode, coarsest first.
    pub const ALL: [Self; 5] = [
        Self::Full,
        Self::Half,
        Self::Quarter,
        Self::Eighth,
        Self::Sixteenth,
    ];

    /// Microsteps per full step (1, 2, 4, 8, 16).
    #[must_use]
    pub fn divisor(self) -> u32 {
        match self {
            Self::Full => 1,
            Self::Half => 2,
            Self::Quarter => 4,
            Self::Eighth => 8,
            Self::Sixteenth => 16,
        }
    }

    /// The mode with `divisor` microsteps per full step.
    #[must_use]
    pub fn from_divisor(divisor: u32) -> Option<Self> {
        Self::ALL.into_iter().find(|m| m.divisor() == divisor)
    }

    /// Levels of `[MS1, MS2, MS3]` (`true` = high) per the datasheet table.
    #[must_use]
    pub fn pin_levels(self) -> [bool; 3] {
        match self {
            Self::Full => [false, false, false],
            Self::Half => [true, false, false],
            Self::Quarter => [false, true, false],
            Self::Eighth => [true, true, false],
            Self::Sixteenth => [true, true, true],
        }
    }
}

impl FromStr for Microstep {
    type Err = TurntableError;

    /// Accepts `full`, `half`, `quarter`, `eighth`, `sixteenth` or the
    /// divisor `1`, `2`, `4`, `8`, `16`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let m = match s.trim().to_ascii_lowercase().as_str() {
            "full" | "1" => Self::Full,
            "half" | "2" => Self::Half,
            "quarter" | "4" => Self::Quarter,
            "eighth" | "8" => Self::Eighth,
            "sixteenth" | "16" => Self::Sixteenth,
            _ => {
                return Err(TurntableError::Config(format!(
                    "microstep mode {s:?}: expected full, half, quarter, eighth, sixteenth \
                     (or 1, 2, 4, 8, 16)"
                )));
            }
        };
        Ok(m)
    }
}

impl fmt::Display for Microstep {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Full => "full",
            Self::Half => "half",
            Self::Quarter => "quarter",
            Self::Eighth => "eighth",
            Self::Sixteenth => "sixteenth",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::Microstep;

    #[test]
    fn microstep_table_matches_datasheet() {
        use Microstep::*;
        let table = [
            (Full, [false, false, false], 1),
            (Half, [true, false, false], 2),
            (Quarter, [false, true, false], 4),
            (Eighth, [true, true, false], 8),
            (Sixteenth, [true, true, true], 16),
        ];
        for (m, levels, div) in table {
            assert_eq!(m.pin_levels(), levels);
            assert_eq!(m.divisor(), div);
            assert_eq!(Microstep::from_divisor(div), Some(m));
            assert_eq!(m.to_string().parse::<Microstep>().unwrap(), m);
        }
        assert!("tenth".parse::<Microstep>().is_err());
    }
}
