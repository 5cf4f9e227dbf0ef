//! `sensor_msgs`: images, camera models, point clouds, IMU, GNSS.

use serde::{Deserialize, Serialize};

use super::{messages, Header};

/// `sensor_msgs/msg/Image`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Image {
    /// The capture's time and the camera's (optical) frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// `bgra8`, `rgb8`, `32FC1`, … (ROS's `sensor_msgs/image_encodings`).
    pub encoding: String,
    /// 0: little-endian.
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// The pixels, row by row from the top left.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// `sensor_msgs/msg/RegionOfInterest`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct RegionOfInterest {
    /// Left edge.
    pub x_offset: u32,
    /// Top edge.
    pub y_offset: u32,
    /// Rows (0: the whole image).
    pub height: u32,
    /// Columns (0: the whole image).
    pub width: u32,
    /// Whether the region is to be rectified.
    pub do_rectify: bool,
}

/// `sensor_msgs/msg/CameraInfo`: a pinhole camera's model.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraInfo {
    /// The image's stamp and frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// `plumb_bob`.
    pub distortion_model: String,
    /// Distortion coefficients (all zero: an ideal pinhole).
    pub d: Vec<f64>,
    /// Intrinsics, row-major 3x3.
    pub k: [f64; 9],
    /// Rectification, row-major 3x3 (identity).
    pub r: [f64; 9],
    /// Projection, row-major 3x4.
    pub p: [f64; 12],
    /// Horizontal binning (0: none).
    pub binning_x: u32,
    /// Vertical binning (0: none).
    pub binning_y: u32,
    /// The region of interest (the whole image).
    pub roi: RegionOfInterest,
}

/// `sensor_msgs/msg/PointField`: one field of a [`PointCloud2`]'s points.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PointField {
    /// `x`, `intensity`, …
    pub name: String,
    /// Byte offset in a point.
    pub offset: u32,
    /// [`PointField::FLOAT32`], [`PointField::UINT32`], …
    pub datatype: u8,
    /// Elements (1).
    pub count: u32,
}

impl PointField {
    /// `PointField.INT8`.
    pub const INT8: u8 = 1;
    /// `PointField.UINT32`.
    pub const UINT32: u8 = 6;
    /// `PointField.FLOAT32`.
    pub const FLOAT32: u8 = 7;

    /// A field of one element.
    pub fn new(name: &str, offset: u32, datatype: u8) -> Self {
        Self {
            name: name.to_owned(),
            offset,
            datatype,
            count: 1,
        }
    }
}

/// `sensor_msgs/msg/PointCloud2`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PointCloud2 {
    /// The scan's time and the sensor's frame.
    pub header: Header,
    /// 1: an unordered cloud.
    pub height: u32,
    /// Points.
    pub width: u32,
    /// What each point holds.
    pub fields: Vec<PointField>,
    /// 0: little-endian.
    pub is_bigendian: bool,
    /// Bytes per point.
    pub point_step: u32,
    /// Bytes per row (`point_step * width`).
    pub row_step: u32,
    /// The points.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
    /// No invalid (NaN) points.
    pub is_dense: bool,
}

/// `sensor_msgs/msg/Imu`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// The reading's time and the sensor's frame.
    pub header: Header,
    /// The sensor's orientation in `map`.
    pub orientation: super::Quaternion,
    /// Row-major 3x3 (zero: known exactly).
    pub orientation_covariance: [f64; 9],
    /// Radians per second, sensor axes.
    pub angular_velocity: super::Vector3,
    /// Row-major 3x3.
    pub angular_velocity_covariance: [f64; 9],
    /// Metres per second squared, sensor axes (gravity included).
    pub linear_acceleration: super::Vector3,
    /// Row-major 3x3.
    pub linear_acceleration_covariance: [f64; 9],
}

/// `sensor_msgs/msg/NavSatStatus`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct NavSatStatus {
    /// `STATUS_FIX` (0): a fix.
    pub status: i8,
    /// `SERVICE_GPS` (1).
    pub service: u16,
}

/// `sensor_msgs/msg/NavSatFix`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NavSatFix {
    /// The reading's time and the receiver's frame.
    pub header: Header,
    /// Fix and service.
    pub status: NavSatStatus,
    /// Degrees, north positive.
    pub latitude: f64,
    /// Degrees, east positive.
    pub longitude: f64,
    /// Metres above the reference ellipsoid.
    pub altitude: f64,
    /// Row-major 3x3, metres squared (east, north, up).
    pub position_covariance: [f64; 9],
    /// `COVARIANCE_TYPE_UNKNOWN` (0) … `KNOWN` (3).
    pub position_covariance_type: u8,
}

/// `sensor_msgs/msg/CompressedImage` (part of a [`Marker`](super::Marker)).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CompressedImage {
    /// Stamp and frame.
    pub header: Header,
    /// `png`, `jpeg`, …
    pub format: String,
    /// The compressed bytes.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

messages! {
    Image => "sensor_msgs", "Image";
    CameraInfo => "sensor_msgs", "CameraInfo";
    PointCloud2 => "sensor_msgs", "PointCloud2";
    Imu => "sensor_msgs", "Imu";
    NavSatFix => "sensor_msgs", "NavSatFix";
}
