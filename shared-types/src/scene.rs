//! Scene names, as `sim-server --scene`, `sim-client load` and a load
//! request spell them: `default`, `empty`, `town`, `flat` or `boxes:N`. One grammar, so a
//! client refuses a bad name with the same words as the server, before it
//! asks.

use std::fmt;
use std::str::FromStr;

/// The most boxes `boxes:N` accepts.
pub const MAX_SCENE_BOXES: u32 = 100_000;

/// A scene's name, parsed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneName {
    /// `default`: the demo scene.
    Default,
    /// `empty`: no actors.
    Empty,
    /// `town`: a grid of roads with junctions and a loop, on a flat ground.
    Town,
    /// `flat`: a flat ground and nothing on it (the world CARLA's
    /// `generate_opendrive_world` builds).
    Flat,
    /// `boxes:N`: ground plus N boxes, N in `1..=`[`MAX_SCENE_BOXES`].
    Boxes(u32),
}

/// Why a scene name was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SceneNameError {
    /// Not one of the known scenes.
    #[error("unknown scene '{0}': expected 'default', 'empty', 'town', 'flat' or 'boxes:N'")]
    Unknown(String),
    /// `boxes:N` with N not a whole number in range.
    #[error("invalid box count in '{0}': boxes:N needs N in 1..={MAX_SCENE_BOXES}")]
    BoxCount(String),
}

impl FromStr for SceneName {
    type Err = SceneNameError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "default" => Ok(Self::Default),
            "empty" => Ok(Self::Empty),
            "town" => Ok(Self::Town),
            "flat" => Ok(Self::Flat),
            _ => {
                let count = s
                    .strip_prefix("boxes:")
                    .ok_or_else(|| SceneNameError::Unknown(s.to_owned()))?;
                match count.parse::<u32>() {
                    Ok(n) if (1..=MAX_SCENE_BOXES).contains(&n) => Ok(Self::Boxes(n)),
                    _ => Err(SceneNameError::BoxCount(s.to_owned())),
                }
            }
        }
    }
}

impl fmt::Display for SceneName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Default => f.write_str("default"),
            Self::Empty => f.write_str("empty"),
            Self::Town => f.write_str("town"),
            Self::Flat => f.write_str("flat"),
            Self::Boxes(n) => write!(f, "boxes:{n}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_counts_out_of_range_name_the_range() {
        for bad in [
            "boxes:0",
            "boxes:-1",
            "boxes:NaN",
            "boxes:1e300",
            "boxes:100001",
        ] {
            let e = bad.parse::<SceneName>().unwrap_err();
            assert_eq!(e, SceneNameError::BoxCount(bad.to_owned()));
            assert!(
                e.to_string().contains("boxes:N needs N in 1..=100000"),
                "{e}"
            );
        }
        assert_eq!("boxes:3".parse(), Ok(SceneName::Boxes(3)));
        assert!(matches!(
            "town10".parse::<SceneName>(),
            Err(SceneNameError::Unknown(_))
        ));
    }

    #[test]
    fn every_scene_name_prints_back_and_the_error_lists_them() {
        for name in ["default", "empty", "town", "flat", "boxes:7"] {
            assert_eq!(name.parse::<SceneName>().unwrap().to_string(), name);
        }
        let e = "Town10HD_Opt".parse::<SceneName>().unwrap_err();
        assert_eq!(
            e.to_string(),
            "unknown scene 'Town10HD_Opt': expected 'default', 'empty', 'town', 'flat' or 'boxes:N'"
        );
    }
}
