//! What a frame does when its fixed delta is longer than substepping allows
//! (`fixed_delta_seconds > max_substep_delta_time * max_substeps`): refuse
//! the settings (simbus's rule), clamp physics as CARLA does, or stretch the
//! substeps. The arithmetic of each rule lives here, so the server that steps
//! and every client that reads a frame agree on it.

use std::fmt;
use std::str::FromStr;

use crate::wire::wire_enum;

wire_enum! {
    /// What a frame longer than `max_substeps × max_substep_delta_time`
    /// does. Travels in [`WireSettings::substep_rule`](crate::settings_wire::WireSettings::substep_rule); 0 (what every
    /// older peer and recording holds) is [`SubstepRule::Refuse`].
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize)]
    #[serde(rename_all = "lowercase")]
    pub enum SubstepRule {
        /// Such settings are refused (simbus's rule, the native default).
        #[default]
        Refuse = 0,
        /// CARLA's behaviour: physics advances at most `max_substeps`
        /// substeps of `max_substep_delta_time` while the frame's timestamp
        /// advances the full delta; each such frame is flagged
        /// [`FrameHeader::PHYSICS_CLAMPED`](crate::frame::FrameHeader::PHYSICS_CLAMPED).
        Clamp = 1,
        /// Substeps are lengthened to `delta / max_substeps`, so physics
        /// keeps pace with time (each such frame is flagged
        /// [`FrameHeader::SUBSTEPS_CAPPED`](crate::frame::FrameHeader::SUBSTEPS_CAPPED)).
        Stretch = 2,
    }
}

impl SubstepRule {
    /// The word used on command lines, in JSON and in Python.
    pub fn name(self) -> &'static str {
        match self {
            Self::Refuse => "refuse",
            Self::Clamp => "clamp",
            Self::Stretch => "stretch",
        }
    }

    /// The physics time, in nanoseconds, that a frame of `delta_ns` runs
    /// under this rule with substeps of at most `max_substep_ns`, at most
    /// `max_substeps` of them: `delta_ns`, except under
    /// [`SubstepRule::Clamp`], where it is at most `max_substep_ns ×
    /// max_substeps` (CARLA's clamp). Without substepping, `delta_ns`.
    pub fn physics_ns(
        self,
        delta_ns: u64,
        substepping: bool,
        max_substep_ns: u64,
        max_substeps: u32,
    ) -> u64 {
        match self {
            Self::Clamp if substepping => {
                delta_ns.min(max_substep_ns.saturating_mul(u64::from(max_substeps.max(1))))
            }
            _ => delta_ns,
        }
    }
}

impl fmt::Display for SubstepRule {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A word that names no [`SubstepRule`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("'{0}' is not a substep rule: refuse, clamp or stretch")]
pub struct UnknownSubstepRule(pub String);

impl FromStr for SubstepRule {
    type Err = UnknownSubstepRule;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|rule| rule.name() == text)
            .ok_or_else(|| UnknownSubstepRule(text.to_owned()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rules_round_trip_through_their_names() {
        for rule in SubstepRule::ALL {
            assert_eq!(rule.name().parse::<SubstepRule>(), Ok(rule));
            assert_eq!(rule.to_string(), rule.name());
        }
        assert_eq!(
            "carla".parse::<SubstepRule>().unwrap_err().to_string(),
            "'carla' is not a substep rule: refuse, clamp or stretch"
        );
        assert_eq!(SubstepRule::default(), SubstepRule::Refuse);
        assert_eq!(SubstepRule::try_from(0), Ok(SubstepRule::Refuse));
    }

    #[test]
    fn only_clamp_shortens_physics_and_only_past_the_limit() {
        let ms = 1_000_000;
        // CARLA's example: 0.2 s frames, 10 substeps of at most 0.01 s.
        assert_eq!(
            SubstepRule::Clamp.physics_ns(200 * ms, true, 10 * ms, 10),
            100 * ms
        );
        assert_eq!(
            SubstepRule::Clamp.physics_ns(50 * ms, true, 10 * ms, 10),
            50 * ms
        );
        assert_eq!(
            SubstepRule::Clamp.physics_ns(200 * ms, false, 10 * ms, 10),
            200 * ms
        );
        for rule in [SubstepRule::Refuse, SubstepRule::Stretch] {
            assert_eq!(rule.physics_ns(200 * ms, true, 10 * ms, 10), 200 * ms);
        }
    }

    /// CARLA's example: synchronous, 0.2 s frames, the default 0.01 s x 10.
    fn carla_example(rule: SubstepRule) -> crate::settings::WorldSettings {
        crate::settings::WorldSettings {
            synchronous_mode: true,
            fixed_delta_seconds: Some(0.2),
            substep_rule: rule,
            ..Default::default()
        }
    }

    #[test]
    fn refuse_names_the_rule_and_the_alternatives_in_numbers() {
        let error = carla_example(SubstepRule::Refuse).validate().unwrap_err();
        assert_eq!(
            error.to_string(),
            "substep rule violated: fixed_delta_seconds (0.2 s) must be <= \
             max_substep_delta_time (0.01 s) * max_substeps (10) = 0.1 s \
             (substep rule 'refuse'; 'clamp' runs CARLA's way: physics advances 0.1 s per \
             0.2 s frame; 'stretch' lengthens the substeps to 0.02 s)"
        );
    }

    #[test]
    fn clamp_and_stretch_accept_long_frames_and_say_what_they_do() {
        use crate::settings::SettingsWarning;
        let clamp = carla_example(SubstepRule::Clamp);
        assert_eq!(clamp.validate(), Ok(()));
        assert!(clamp.clamps_physics());
        let warnings = clamp.warnings();
        // 10 substeps of 0.01 s: not long substeps, but a long, clamped frame.
        assert!(matches!(
            warnings[..],
            [
                SettingsWarning::LongFrame { .. },
                SettingsWarning::PhysicsClamped { .. }
            ]
        ));
        assert_eq!(
            warnings[1].to_string(),
            "substep rule 'clamp': physics advances 0.100 s per 0.200 s frame \
             (10 substeps of 0.010 s), as in CARLA; frames are flagged clamped"
        );
        let stretch = carla_example(SubstepRule::Stretch);
        assert_eq!(stretch.validate(), Ok(()));
        assert!(!stretch.clamps_physics());
        assert!(matches!(
            stretch.warnings()[..],
            [
                SettingsWarning::LongFrame { .. },
                SettingsWarning::LongSubstep { substep_seconds }
            ] if (substep_seconds - 0.02).abs() < 1e-12
        ));
        // Within the limit every rule is the same.
        let short = crate::settings::WorldSettings {
            fixed_delta_seconds: Some(0.05),
            ..clamp
        };
        assert!(!short.clamps_physics());
        assert!(short.warnings().is_empty());
        assert_eq!(
            clamp.to_string(),
            "sync, fixed step 0.2 s, substepping <= 0.01 s x 10, substep rule clamp"
        );
    }
}
