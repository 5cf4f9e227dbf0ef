//! What the image cameras write: the pixel, CARLA 0.9.16's semantic tags
//! (`carla/rpc/ObjectLabel.h`) and their CityScapes colours
//! (`carla/image/CityScapesPalette.h`), the instance encoding
//! (`Tagger::GetLabelColor`), and the sun that lights the RGB camera.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

/// One pixel of an RGB, semantic or instance segmentation image, in
/// CARLA's byte order: blue, green, red, alpha.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::Bgra/1")]
pub struct Bgra {
    /// Blue.
    pub b: u8,
    /// Green.
    pub g: u8,
    /// Red.
    pub r: u8,
    /// Alpha (255: opaque, as CARLA writes it).
    pub a: u8,
}

impl Bgra {
    /// An opaque pixel of colour (`r`, `g`, `b`).
    pub const fn rgb(r: u8, g: u8, b: u8) -> Self {
        Self { b, g, r, a: 255 }
    }

    /// A semantic segmentation pixel: `tag` in red, as CARLA encodes it.
    pub const fn semantic(tag: SemanticTag) -> Self {
        Self::rgb(tag as u8, 0, 0)
    }

    /// An instance segmentation pixel: `tag` in red, the low byte of
    /// `actor` in green and its next byte in blue, as CARLA encodes it.
    pub const fn instance(tag: SemanticTag, actor: u64) -> Self {
        Self::rgb(tag as u8, (actor & 0xff) as u8, ((actor >> 8) & 0xff) as u8)
    }
}

/// CARLA 0.9.16's semantic tags (`carla::rpc::CityObjectLabel`).
#[allow(missing_docs)]
#[repr(u8)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SemanticTag {
    None = 0,
    Roads = 1,
    Sidewalks = 2,
    Buildings = 3,
    Walls = 4,
    Fences = 5,
    Poles = 6,
    TrafficLight = 7,
    TrafficSigns = 8,
    Vegetation = 9,
    Terrain = 10,
    Sky = 11,
    Pedestrians = 12,
    Rider = 13,
    Car = 14,
    Truck = 15,
    Bus = 16,
    Train = 17,
    Motorcycle = 18,
    Bicycle = 19,
    Static = 20,
    Dynamic = 21,
    Other = 22,
    Water = 23,
    RoadLines = 24,
    Ground = 25,
    Bridge = 26,
    RailTrack = 27,
    GuardRail = 28,
}

/// CARLA's CityScapes palette: the colour (r, g, b) of each tag, by id.
pub const CITYSCAPES_PALETTE: [[u8; 3]; 29] = [
    [0, 0, 0],
    [128, 64, 128],
    [244, 35, 232],
    [70, 70, 70],
    [102, 102, 156],
    [190, 153, 153],
    [153, 153, 153],
    [250, 170, 30],
    [220, 220, 0],
    [107, 142, 35],
    [152, 251, 152],
    [70, 130, 180],
    [220, 20, 60],
    [255, 0, 0],
    [0, 0, 142],
    [0, 0, 70],
    [0, 60, 100],
    [0, 80, 100],
    [0, 0, 230],
    [119, 11, 32],
    [110, 190, 160],
    [170, 120, 50],
    [55, 90, 80],
    [45, 60, 150],
    [157, 234, 50],
    [81, 0, 81],
    [150, 100, 100],
    [230, 150, 140],
    [180, 165, 180],
];

/// The CityScapes colour (r, g, b) of tag id `tag`, as CARLA's
/// `CityScapesPalette::GetColor` gives it (ids past the table wrap).
pub fn cityscapes(tag: u8) -> [u8; 3] {
    CITYSCAPES_PALETTE[usize::from(tag) % CITYSCAPES_PALETTE.len()]
}

/// Where the sun is: CARLA's `sun_azimuth_angle` and `sun_altitude_angle`
/// (degrees), which a weather sets.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Sun {
    /// Degrees around the vertical, from CARLA's +x towards its +y.
    pub azimuth: f32,
    /// Degrees above the horizon (negative: below it, night).
    pub altitude: f32,
}

impl Default for Sun {
    /// CARLA's `ClearNoon`: azimuth −1°, altitude 45°.
    fn default() -> Self {
        Self {
            azimuth: -1.0,
            altitude: 45.0,
        }
    }
}

impl Sun {
    /// Whether both angles are finite (any angle is a place in the sky,
    /// as in CARLA: an altitude of 120° is 60° up on the other side).
    pub fn valid(&self) -> bool {
        self.azimuth.is_finite() && self.altitude.is_finite()
    }

    /// Its height above the horizon, degrees in −90..=90.
    pub fn elevation(&self) -> f32 {
        self.direction()[1].clamp(-1.0, 1.0).asin().to_degrees()
    }

    /// The unit vector towards the sun in simbus's world axes (X forward,
    /// Y up, Z right: CARLA's x, z, y).
    pub fn direction(&self) -> [f32; 3] {
        let (az, alt) = (self.azimuth.to_radians(), self.altitude.to_radians());
        [alt.cos() * az.cos(), alt.sin(), alt.cos() * az.sin()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pixels_encode_tags_and_ids_as_carla_does() {
        assert_eq!(std::mem::size_of::<Bgra>(), 4);
        let p = Bgra::instance(SemanticTag::Car, 0x1234);
        assert_eq!(bytemuck::bytes_of(&p), &[0x12, 0x34, 14, 255]);
        assert_eq!(Bgra::semantic(SemanticTag::RoadLines).r, 24);
        assert_eq!(cityscapes(SemanticTag::Car as u8), [0, 0, 142]);
        assert_eq!(cityscapes(SemanticTag::GuardRail as u8), [180, 165, 180]);
        assert_eq!(cityscapes(29), cityscapes(0));
    }

    #[test]
    fn the_sun_points_up_at_noon_and_along_its_azimuth() {
        let overhead = Sun {
            azimuth: 0.0,
            altitude: 90.0,
        }
        .direction();
        assert!((overhead[1] - 1.0).abs() < 1e-6);
        let east = Sun {
            azimuth: 90.0,
            altitude: 0.0,
        }
        .direction();
        assert!((east[2] - 1.0).abs() < 1e-6 && east[0].abs() < 1e-6);
        let past_zenith = Sun {
            azimuth: 0.0,
            altitude: 120.0,
        };
        assert!(past_zenith.valid() && (past_zenith.elevation() - 60.0).abs() < 1e-3);
        assert!(!Sun {
            azimuth: 0.0,
            altitude: f32::NAN
        }
        .valid());
    }
}
