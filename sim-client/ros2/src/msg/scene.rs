//! `visualization_msgs`: the scene for rviz2.

use serde::{Deserialize, Serialize};

use super::{messages, CompressedImage, Duration, Header, Point, Pose, Vector3};

/// `std_msgs/msg/ColorRGBA`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct ColorRgba {
    /// Red, 0..1.
    pub r: f32,
    /// Green, 0..1.
    pub g: f32,
    /// Blue, 0..1.
    pub b: f32,
    /// Opacity, 0..1.
    pub a: f32,
}

/// `visualization_msgs/msg/UVCoordinate`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct UvCoordinate {
    /// U.
    pub u: f32,
    /// V.
    pub v: f32,
}

/// `visualization_msgs/msg/MeshFile`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MeshFile {
    /// The file's name.
    pub filename: String,
    /// Its bytes.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// `visualization_msgs/msg/Marker` (ROS 2 Kilted's, textures and mesh
/// files included).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Marker {
    /// Frame and time.
    pub header: Header,
    /// The marker's namespace (`vehicles`, `walkers`, …).
    pub ns: String,
    /// Its id in the namespace (the actor's).
    pub id: i32,
    /// [`Marker::CUBE`], [`Marker::CYLINDER`], …
    pub r#type: i32,
    /// [`Marker::ADD`] or [`Marker::DELETEALL`].
    pub action: i32,
    /// Where, in `header.frame_id`.
    pub pose: Pose,
    /// Size, metres.
    pub scale: Vector3,
    /// Colour.
    pub color: ColorRgba,
    /// How long it shows (0: until replaced).
    pub lifetime: Duration,
    /// Whether it follows its frame.
    pub frame_locked: bool,
    /// Points (line and point markers).
    pub points: Vec<Point>,
    /// Per-point colours.
    pub colors: Vec<ColorRgba>,
    /// A texture's resource name.
    pub texture_resource: String,
    /// A texture.
    pub texture: CompressedImage,
    /// Texture coordinates.
    pub uv_coordinates: Vec<UvCoordinate>,
    /// Text (text markers).
    pub text: String,
    /// A mesh's resource name.
    pub mesh_resource: String,
    /// A mesh.
    pub mesh_file: MeshFile,
    /// Whether a mesh uses its own materials.
    pub mesh_use_embedded_materials: bool,
}

impl Marker {
    /// `Marker.CUBE`.
    pub const CUBE: i32 = 1;
    /// `Marker.SPHERE`.
    pub const SPHERE: i32 = 2;
    /// `Marker.CYLINDER`.
    pub const CYLINDER: i32 = 3;
    /// `Marker.ADD`.
    pub const ADD: i32 = 0;
    /// `Marker.DELETEALL`.
    pub const DELETEALL: i32 = 3;
}

/// `visualization_msgs/msg/MarkerArray`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct MarkerArray {
    /// The markers.
    pub markers: Vec<Marker>,
}

messages! {
    Marker => "visualization_msgs", "Marker";
    MarkerArray => "visualization_msgs", "MarkerArray";
}
