//! Condition states from crack width, as element-level bridge inspection
//! records them, and their settings, the `[condition]` table of
//! `postflight.toml`.
//!
//! The defaults are the AASHTO *Manual for Bridge Element Inspection*'s
//! width classes for its cracking defects (see docs/condition.md): for
//! reinforced concrete (defect 1130) a crack narrower than 0.012 in is
//! insignificant, 0.012 to 0.05 in moderate and wider than 0.05 in wide; for
//! prestressed concrete (defect 1110) the limits are 0.004 in and 0.009 in.
//! An insignificant crack leaves its length in condition state 1 (good), a
//! moderate one puts it in 2 (fair), a wide one in 3 (poor). State 4
//! (severe) asks for a structural review, which no width decides; an
//! inspector sets it in the review queue.

use crate::outputs::localise::WidthRecord;
use crate::setting::InvalidSetting;

crate::settings! {
    table = "condition", keys = keys;
    /// `[condition]`: the width limits that put a crack's length in a
    /// condition state; an unset limit is the material's.
    #[derive(Copy)]
    pub struct ConditionSettings =>
    /// The material and its width limits.
    #[derive(Copy)]
    struct ConditionConfig {
        /// The structure's material, whose cracking defect's width limits
        /// apply.
        #[arg(long, value_enum, value_name = "MATERIAL")]
        material: Material = Material::ReinforcedConcrete,
        /// Cracks narrower than this are insignificant (condition state 1),
        /// millimetres (default: the material's).
        #[arg(long = "insignificant-below", value_name = "MM")]
        insignificant_below_mm: f64,
        /// Cracks wider than this are wide (condition state 3),
        /// millimetres (default: the material's).
        #[arg(long = "wide-above", value_name = "MM")]
        wide_above_mm: f64,
    }
}

/// Millimetres in an inch.
const MM_PER_INCH: f64 = 25.4;

/// A structure's material, as the manual's cracking defects name them.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    serde::Serialize,
    serde::Deserialize,
    clap::ValueEnum,
)]
#[serde(rename_all = "snake_case")]
pub enum Material {
    /// Reinforced concrete (defect 1130, Cracking (RC and Other)).
    #[default]
    ReinforcedConcrete,
    /// Prestressed concrete (defect 1110, Cracking (PSC)).
    PrestressedConcrete,
}

impl Material {
    /// The manual's width limits for this material's cracking defect.
    pub fn limits(self) -> CrackLimits {
        let (insignificant, wide) = match self {
            Self::ReinforcedConcrete => (0.012, 0.05),
            Self::PrestressedConcrete => (0.004, 0.009),
        };
        CrackLimits {
            insignificant_below_mm: insignificant * MM_PER_INCH,
            wide_above_mm: wide * MM_PER_INCH,
        }
    }
}

/// Width limits between the condition states of cracking.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CrackLimits {
    /// Narrower: insignificant (state 1).
    pub insignificant_below_mm: f64,
    /// Wider: wide (state 3); between the two: moderate (state 2).
    pub wide_above_mm: f64,
}

impl Default for CrackLimits {
    fn default() -> Self {
        Material::default().limits()
    }
}

impl CrackLimits {
    /// The condition state a crack `width_mm` wide puts its length in.
    pub fn state(&self, width_mm: f64) -> ConditionState {
        if width_mm < self.insignificant_below_mm {
            ConditionState::Good
        } else if width_mm <= self.wide_above_mm {
            ConditionState::Fair
        } else {
            ConditionState::Poor
        }
    }

    /// The state of a crack whose width is only known to be below
    /// `below_mm`: `None` when that bound straddles a limit.
    pub fn state_below(&self, below_mm: f64) -> Option<ConditionState> {
        (below_mm <= self.insignificant_below_mm).then_some(ConditionState::Good)
    }

    /// The state a candidate's measured `width` puts it in, and how sure
    /// that is: by its widest where measured (its uncertainty one standard
    /// deviation of a normal error), by its bound where below resolution
    /// (sure: the bound is below the insignificant limit); `None` when
    /// nothing was measured or the bound straddles a limit.
    pub fn state_of(&self, width: &WidthRecord) -> Option<StateCall> {
        match (width.max_mm, width.narrower_than_mm) {
            (Some(max), _) => Some(self.call(max, width.uncertainty_mm.unwrap_or(0.0))),
            (None, Some(below)) => self.state_below(below).map(|state| StateCall {
                state,
                probability: 1.0,
                other: None,
                other_probability: None,
            }),
            (None, None) => None,
        }
    }

    /// The state of a width `mm` good to `sigma_mm` (one standard
    /// deviation), with the state across a limit within `sigma_mm` of it.
    pub fn call(&self, mm: f64, sigma_mm: f64) -> StateCall {
        let state = self.state(mm);
        // How likely the width is below each limit.
        let below = |limit: f64| {
            if sigma_mm > 0.0 {
                0.5 * (1.0 + libm::erf((limit - mm) / (sigma_mm * std::f64::consts::SQRT_2)))
            } else if mm < limit {
                1.0
            } else {
                0.0
            }
        };
        let (insignificant, wide) = (
            below(self.insignificant_below_mm),
            below(self.wide_above_mm),
        );
        let likely = |s: ConditionState| match s {
            ConditionState::Good => insignificant,
            ConditionState::Fair => wide - insignificant,
            _ => 1.0 - wide,
        };
        let straddled = [
            (
                self.insignificant_below_mm,
                [ConditionState::Good, ConditionState::Fair],
            ),
            (
                self.wide_above_mm,
                [ConditionState::Fair, ConditionState::Poor],
            ),
        ];
        let other = straddled
            .into_iter()
            .filter(|(limit, _)| (mm - limit).abs() <= sigma_mm)
            .flat_map(|(_, sides)| sides)
            .filter(|s| *s != state)
            .max_by(|a, b| likely(*a).total_cmp(&likely(*b)));
        StateCall {
            state,
            probability: likely(state),
            other,
            other_probability: other.map(likely),
        }
    }
}

crate::table! {
    /// The condition state a crack's width puts it in, and how sure that is:
    /// where its width's interval (its uncertainty either side) straddles a
    /// limit, the state on the other side too, so an inspector knows which
    /// cracks to gauge on site.
    #[derive(Copy, serde::Serialize, serde::Deserialize)]
    pub struct StateCall {
        /// The state its width puts its length in.
        #[serde(rename = "condition")]
        state: ConditionState as condition_state,
        /// How likely its width is within that state's limits, its
        /// uncertainty one standard deviation of a normal error.
        #[serde(rename = "condition_probability")]
        probability: f64 as condition_probability,
        /// The likelier state across a limit its width's interval straddles;
        /// none where the interval lies within one state.
        #[serde(rename = "other_condition")]
        other: Option<ConditionState> as other_condition_state,
        /// How likely its width is within that state's limits.
        #[serde(rename = "other_condition_probability")]
        other_probability: Option<f64> as other_condition_probability,
    }
}

impl ConditionConfig {
    /// The limits: the material's, with those given over them.
    pub fn limits(&self) -> CrackLimits {
        let material = self.material.limits();
        CrackLimits {
            insignificant_below_mm: self
                .insignificant_below_mm
                .unwrap_or(material.insignificant_below_mm),
            wide_above_mm: self.wide_above_mm.unwrap_or(material.wide_above_mm),
        }
    }

    /// Refuse limits that cannot work.
    pub fn check(&self) -> Result<(), InvalidSetting> {
        let limits = self.limits();
        InvalidSetting::check(
            limits.insignificant_below_mm > 0.0,
            keys::insignificant_below_mm,
            limits.insignificant_below_mm,
            "above 0 millimetres",
        )?;
        InvalidSetting::check(
            limits.wide_above_mm >= limits.insignificant_below_mm,
            keys::wide_above_mm,
            limits.wide_above_mm,
            &format!(
                "at least {} ({} mm)",
                keys::insignificant_below_mm,
                limits.insignificant_below_mm
            ),
        )
    }
}

crate::kind! {
    /// A condition state of the manual: 1 good to 4 severe.
    pub enum ConditionState("condition state") {
        Good = "good",
        Fair = "fair",
        Poor = "poor",
        Severe = "severe",
    }
}

impl ConditionState {
    /// The state's number, 1 to 4, as element-level records keep it.
    pub fn number(self) -> u8 {
        match self {
            Self::Good => 1,
            Self::Fair => 2,
            Self::Poor => 3,
            Self::Severe => 4,
        }
    }

    /// The state numbered `n`.
    pub fn from_number(n: u8) -> Option<Self> {
        Self::ALL.get(usize::from(n).checked_sub(1)?).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_manuals_limits_in_millimetres() {
        let rc = Material::ReinforcedConcrete.limits();
        assert!((rc.insignificant_below_mm - 0.3048).abs() < 1e-9);
        assert!((rc.wide_above_mm - 1.27).abs() < 1e-9);
        assert_eq!(rc.state(0.2), ConditionState::Good);
        assert_eq!(rc.state(0.8), ConditionState::Fair);
        assert_eq!(rc.state(1.5), ConditionState::Poor);
        let psc = Material::PrestressedConcrete.limits();
        assert_eq!(psc.state(0.2), ConditionState::Fair);
        assert_eq!(psc.state(0.3), ConditionState::Poor);
        assert_eq!(rc.state_below(0.25), Some(ConditionState::Good));
        assert_eq!(rc.state_below(0.5), None);
    }

    #[test]
    fn a_width_within_its_uncertainty_of_a_limit_names_both_states() {
        let rc = Material::ReinforcedConcrete.limits();
        // 0.28 mm, good to 0.05 mm: 1 good, but within reach of 0.3048 mm.
        let near = rc.call(0.28, 0.05);
        assert_eq!(
            (near.state, near.other),
            (ConditionState::Good, Some(ConditionState::Fair))
        );
        // P(below 0.3048) for a normal error: Phi(0.496) = 0.69.
        assert!((near.probability - 0.690).abs() < 0.002, "{near:?}");
        assert!(
            (near.other_probability.unwrap() - 0.310).abs() < 0.002,
            "{near:?}"
        );
        // 0.31 mm, just over: 2 fair, about as likely as 1 good.
        let over = rc.call(0.31, 0.05);
        assert_eq!(
            (over.state, over.other),
            (ConditionState::Fair, Some(ConditionState::Good))
        );
        assert!(over.probability > 0.5 && over.probability < 0.6, "{over:?}");
        // Far from either limit: sure.
        let far = rc.call(0.8, 0.05);
        assert_eq!((far.state, far.other), (ConditionState::Fair, None));
        assert!(far.probability > 0.999, "{far:?}");
        // Near the wide limit: 3 poor or 2 fair.
        let wide = rc.call(1.3, 0.1);
        assert_eq!(
            (wide.state, wide.other),
            (ConditionState::Poor, Some(ConditionState::Fair))
        );
        // Without an uncertainty, sure of its side.
        assert_eq!(rc.call(0.3, 0.0).probability, 1.0);
        // A bound below the limit is sure; a measured width's record gives its call.
        let below = WidthRecord {
            narrower_than_mm: Some(0.2),
            mm_per_px: 0.5,
            ..WidthRecord::default()
        };
        assert_eq!(
            rc.state_of(&below),
            Some(StateCall {
                state: ConditionState::Good,
                probability: 1.0,
                other: None,
                other_probability: None,
            })
        );
        let measured = WidthRecord {
            max_mm: Some(0.28),
            uncertainty_mm: Some(0.05),
            narrower_than_mm: None,
            ..below
        };
        assert_eq!(rc.state_of(&measured), Some(near));
    }

    #[test]
    fn limits_given_override_the_materials_and_are_checked() {
        let config = ConditionSettings {
            wide_above_mm: Some(2.0),
            ..Default::default()
        }
        .resolve();
        assert_eq!(config.limits().wide_above_mm, 2.0);
        assert!((config.limits().insignificant_below_mm - 0.3048).abs() < 1e-9);
        let bad = ConditionSettings {
            wide_above_mm: Some(0.1),
            ..Default::default()
        }
        .resolve();
        let e = bad.check().unwrap_err();
        assert_eq!(
            e.to_string(),
            "[condition] wide_above_mm must be at least [condition] insignificant_below_mm (0.3048 mm) (it is 0.1)"
        );
        assert_eq!(ConditionState::from_number(3), Some(ConditionState::Poor));
        assert_eq!(ConditionState::from_number(0), None);
    }
}
