//! Checked conversions of numbers people type (seconds, rates, counts,
//! positions) into the values simbus uses. Both command lines parse every
//! numeric flag with one of these, so a bad value (NaN, ±inf, a zero that
//! would mean nothing, an absurd magnitude) is refused with the flag and
//! its range named, exit 2, before anything starts or changes — instead of
//! panicking in a conversion or being sent to a server.
//!
//! Each function has the shape clap's `value_parser` takes; each states
//! its range once, in the constants below or in the limits it cites.
//!
//! ```
//! use simbus_input::{timeout, max_substeps, fps, InputError, Readable};
//!
//! assert_eq!(timeout("2.5").unwrap().as_millis(), 2500);
//! assert!(timeout("1e20").unwrap_err().to_string().contains("at most"));
//! let refused = max_substeps("-1").unwrap_err();
//! assert!(matches!(refused, InputError::NotWhole { start: 1, end: 16, .. }));
//! assert!(refused.to_string().contains("1..=16"));
//! assert!(fps("1e-300").unwrap_err().to_string().contains("0.000277778..=1e6"));
//! assert_eq!(Readable(1.0 / 30.0).to_string(), "0.0333333");
//! ```

mod bounds;
mod error;
mod parse;
mod sensor_values;

pub use bounds::*;
pub use error::InputError;
pub use parse::*;
pub use sensor_values::*;
/// The sensor limits a spec's check enforces, re-exported where the flags
/// that set them are parsed (one definition, in [`shared_types::SensorSpec`]'s module).
pub use shared_types::gnss::MAX_GNSS_SEED;
pub use shared_types::{Exact, Readable, MAX_IMAGE_SIDE, MAX_LIDAR_CHANNELS, MAX_LIDAR_POINTS};
