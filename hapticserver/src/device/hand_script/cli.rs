//! The command-line form of the scripts: their names ([`ScriptKind`]), their options ([`ScriptOptions`]) and
//! the errors of both ([`ScriptError`]), and the `x,y,z` vector syntax ([`parse_vec3_mm`]).
//!
//! Owns: turning a name and options into a checked [`HandScript`] (the fixed timings of each named script are
//! chosen here).
//!
//! Must not: compute a trajectory (that is the parent's `trajectory`) or read the command line itself (the
//! binary's argument parser calls in).

use std::fmt;
use std::str::FromStr;

use thiserror::Error;

use super::{CUT_LINE_HEIGHT_MM, HandScript, SNIP_LINE_HEIGHT_MM, SNIP_PERIOD_S, SNIP_STEP_MM};

/// A script or option given on the command line that cannot be used.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ScriptError {
    /// Not one of the script names.
    #[error(
        "unknown script `{0}`: expected one of hold, press, press-stroke, grasp-pull, cauterize, cut-line, snip-line"
    )]
    UnknownScript(String),
    /// A vector option is not three comma-separated numbers.
    #[error("`{0}` is not a vector `x,y,z` of three finite numbers (mm)")]
    BadVector(String),
    /// A numeric option is out of its domain.
    #[error("script option {option} = {value} is invalid: {reason}")]
    BadOption {
        /// Option name.
        option: &'static str,
        /// The value given.
        value: f32,
        /// Why.
        reason: &'static str,
    },
}

/// The scripts that can be chosen by name (`--script`). [`HandScript::Follow`] has no CLI form.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ScriptKind {
    /// `hold`: [`HandScript::Hold`] at `at_mm`.
    Hold,
    /// `press`: [`HandScript::Press`].
    Press,
    /// `press-stroke`: [`HandScript::PressAndStroke`].
    PressStroke,
    /// `grasp-pull`: [`HandScript::GraspPull`] (press, close, pull up by `depth + 5` mm over 1 s, hold 2 s, open).
    GraspPull,
    /// `cauterize`: [`HandScript::Cauterize`] (press, then button 1 held along a `stroke_mm` line over 2 s).
    Cauterize,
    /// `cut-line`: [`HandScript::CutLine`] (down to [`CUT_LINE_HEIGHT_MM`] above the surface, then a
    /// `stroke_mm` line along +y over 2 s).
    CutLine,
    /// `snip-line`: [`HandScript::SnipLine`] (hinge down to [`SNIP_LINE_HEIGHT_MM`] above the surface, then
    /// `stroke_mm` / 3 mm snips 3 mm apart along +y, [`SNIP_PERIOD_S`] each).
    SnipLine,
}

impl ScriptKind {
    /// The CLI name.
    pub fn name(self) -> &'static str {
        match self {
            ScriptKind::Hold => "hold",
            ScriptKind::Press => "press",
            ScriptKind::PressStroke => "press-stroke",
            ScriptKind::GraspPull => "grasp-pull",
            ScriptKind::Cauterize => "cauterize",
            ScriptKind::CutLine => "cut-line",
            ScriptKind::SnipLine => "snip-line",
        }
    }

    /// Build the script with `options`, checking them.
    pub fn build(self, options: &ScriptOptions) -> Result<HandScript, ScriptError> {
        options.validate()?;
        let o = options;
        Ok(match self {
            ScriptKind::Hold => HandScript::Hold {
                position_mm: o.at_mm,
            },
            ScriptKind::Press => HandScript::Press {
                at_mm: o.at_mm,
                depth_mm: o.depth_mm,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
            },
            ScriptKind::PressStroke => HandScript::PressAndStroke {
                at_mm: o.at_mm,
                depth_mm: o.depth_mm,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
                stroke_mm: o.stroke_mm,
                stroke_period_s: o.stroke_period_s,
            },
            ScriptKind::GraspPull => HandScript::GraspPull {
                at_mm: o.at_mm,
                depth_mm: o.depth_mm,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
                settle_s: o.settle_s,
                pull_mm: o.pull_mm.unwrap_or([0.0, 0.0, o.depth_mm + 5.0]),
                pull_s: 1.0,
                hold_s: o.hold_s,
            },
            ScriptKind::Cauterize => HandScript::Cauterize {
                at_mm: o.at_mm,
                depth_mm: o.depth_mm,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
                stroke_mm: o.stroke_mm,
                stroke_s: 2.0,
            },
            ScriptKind::CutLine => HandScript::CutLine {
                at_mm: o.at_mm,
                height_mm: CUT_LINE_HEIGHT_MM,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
                line_mm: [0.0, o.stroke_mm, 0.0],
                line_s: 2.0,
            },
            ScriptKind::SnipLine => HandScript::SnipLine {
                at_mm: o.at_mm,
                height_mm: SNIP_LINE_HEIGHT_MM,
                approach_mm: o.approach_mm,
                descend_s: o.descend_s,
                step_mm: [0.0, SNIP_STEP_MM, 0.0],
                snips: (o.stroke_mm / SNIP_STEP_MM).ceil().max(1.0) as u32,
                snip_s: SNIP_PERIOD_S,
            },
        })
    }
}

impl FromStr for ScriptKind {
    type Err = ScriptError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim() {
            "hold" => Ok(ScriptKind::Hold),
            "press" => Ok(ScriptKind::Press),
            "press-stroke" | "press_stroke" => Ok(ScriptKind::PressStroke),
            "grasp-pull" | "grasp_pull" => Ok(ScriptKind::GraspPull),
            "cauterize" => Ok(ScriptKind::Cauterize),
            "cut-line" | "cut_line" => Ok(ScriptKind::CutLine),
            "snip-line" | "snip_line" => Ok(ScriptKind::SnipLine),
            other => Err(ScriptError::UnknownScript(other.to_owned())),
        }
    }
}

impl fmt::Display for ScriptKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Options shared by the named scripts (device frame, mm and s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScriptOptions {
    /// Surface point to press at (or the point to hold), mm.
    pub at_mm: [f32; 3],
    /// Depth below the surface, mm.
    pub depth_mm: f32,
    /// Starting height above the surface, mm.
    pub approach_mm: f32,
    /// Descent duration, s.
    pub descend_s: f32,
    /// Stroke amplitude along x, mm.
    pub stroke_mm: f32,
    /// Stroke period, s.
    pub stroke_period_s: f32,
    /// `grasp-pull`: time at depth before the jaws close, s.
    pub settle_s: f32,
    /// `grasp-pull`: the pull, mm (`None`: straight up by `depth_mm + 5`).
    pub pull_mm: Option<[f32; 3]>,
    /// `grasp-pull`: time held after the pull before the jaws open, s.
    pub hold_s: f32,
}

impl Default for ScriptOptions {
    /// Press 5 mm at the device origin from 20 mm above over 2 s; stroke +/- 10 mm every 2 s; a grasp settles
    /// 0.3 s, pulls straight up and holds 2 s.
    fn default() -> Self {
        Self {
            at_mm: [0.0; 3],
            depth_mm: 5.0,
            approach_mm: 20.0,
            descend_s: 2.0,
            stroke_mm: 10.0,
            stroke_period_s: 2.0,
            settle_s: 0.3,
            pull_mm: None,
            hold_s: 2.0,
        }
    }
}

impl ScriptOptions {
    /// Check every option's domain.
    pub fn validate(&self) -> Result<(), ScriptError> {
        for vector in std::iter::once(self.at_mm).chain(self.pull_mm) {
            if !vector.iter().all(|c| c.is_finite()) {
                return Err(ScriptError::BadVector(format!("{vector:?}")));
            }
        }
        let checks: [(&'static str, f32, bool, &'static str); 7] = [
            (
                "depth_mm",
                self.depth_mm,
                self.depth_mm >= 0.0,
                "must be >= 0",
            ),
            (
                "approach_mm",
                self.approach_mm,
                self.approach_mm >= 0.0,
                "must be >= 0",
            ),
            (
                "descend_s",
                self.descend_s,
                self.descend_s >= 0.0,
                "must be >= 0",
            ),
            (
                "stroke_mm",
                self.stroke_mm,
                self.stroke_mm >= 0.0,
                "must be >= 0",
            ),
            (
                "stroke_period_s",
                self.stroke_period_s,
                self.stroke_period_s > 0.0,
                "must be > 0",
            ),
            (
                "settle_s",
                self.settle_s,
                self.settle_s >= 0.0,
                "must be >= 0",
            ),
            ("hold_s", self.hold_s, self.hold_s >= 0.0, "must be >= 0"),
        ];
        for (option, value, ok, reason) in checks {
            if !(ok && value.is_finite()) {
                return Err(ScriptError::BadOption {
                    option,
                    value,
                    reason,
                });
            }
        }
        Ok(())
    }
}

/// Parse `x,y,z` (mm) as given to `--at-mm`.
pub fn parse_vec3_mm(text: &str) -> Result<[f32; 3], ScriptError> {
    let bad = || ScriptError::BadVector(text.to_owned());
    let mut out = [0.0f32; 3];
    let mut parts = text.split(',');
    for slot in &mut out {
        let value: f32 = parts
            .next()
            .ok_or_else(bad)?
            .trim()
            .parse()
            .map_err(|_| bad())?;
        if !value.is_finite() {
            return Err(bad());
        }
        *slot = value;
    }
    if parts.next().is_some() {
        return Err(bad());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cli_forms_parse_and_bad_ones_are_named() {
        assert_eq!("press".parse::<ScriptKind>(), Ok(ScriptKind::Press));
        assert_eq!(
            "press-stroke".parse::<ScriptKind>(),
            Ok(ScriptKind::PressStroke)
        );
        assert_eq!("hold".parse::<ScriptKind>(), Ok(ScriptKind::Hold));
        let err = "poke".parse::<ScriptKind>().unwrap_err();
        assert!(err.to_string().contains("poke"));
        assert_eq!(parse_vec3_mm("1, -2.5,3"), Ok([1.0, -2.5, 3.0]));
        for bad in ["", "1,2", "1,2,3,4", "a,b,c", "1,NaN,2", "1,inf,2"] {
            assert!(parse_vec3_mm(bad).is_err(), "{bad:?} accepted");
        }
        let err = ScriptKind::Press
            .build(&ScriptOptions {
                depth_mm: -1.0,
                ..ScriptOptions::default()
            })
            .unwrap_err();
        assert!(err.to_string().contains("depth_mm"));
        let err = ScriptKind::GraspPull
            .build(&ScriptOptions {
                hold_s: f32::NAN,
                ..ScriptOptions::default()
            })
            .unwrap_err();
        assert!(err.to_string().contains("hold_s"));
        let err = ScriptKind::GraspPull
            .build(&ScriptOptions {
                pull_mm: Some([1.0, f32::INFINITY, 0.0]),
                ..ScriptOptions::default()
            })
            .unwrap_err();
        assert!(matches!(err, ScriptError::BadVector(_)), "{err}");
    }

    #[test]
    fn a_grasp_pull_takes_its_pull_settle_and_hold_from_the_options() {
        let script = ScriptKind::GraspPull
            .build(&ScriptOptions {
                settle_s: 0.8,
                pull_mm: Some([-6.0, 0.0, 8.0]),
                hold_s: 4.0,
                ..ScriptOptions::default()
            })
            .unwrap();
        let HandScript::GraspPull {
            settle_s,
            pull_mm,
            hold_s,
            ..
        } = script
        else {
            panic!("{script:?}");
        };
        assert_eq!((settle_s, pull_mm, hold_s), (0.8, [-6.0, 0.0, 8.0], 4.0));
        let HandScript::GraspPull { pull_mm, .. } = ScriptKind::GraspPull
            .build(&ScriptOptions::default())
            .unwrap()
        else {
            panic!("not a grasp");
        };
        assert_eq!(pull_mm, [0.0, 0.0, 10.0]);
    }
}
