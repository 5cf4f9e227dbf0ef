//! Numbers as people read them back in messages: [`Readable`] for values
//! shown, [`Exact`] for values refused.

use std::fmt;

/// A number as people read it back: at most six significant digits,
/// trailing zeros dropped, in exponent form below 1e-4 and from 1e6 on
/// (`0.0333333`, `0.05`, `3600`, `1e300`), never 300 digits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Readable(pub f64);

impl fmt::Display for Readable {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        if !x.is_finite() || x == 0.0 {
            return write!(f, "{x}");
        }
        let magnitude = x.abs();
        if (1e-4..1e6).contains(&magnitude) {
            let decimals = (5 - magnitude.log10().floor() as i32).max(0) as usize;
            let text = format!("{x:.decimals$}");
            let text = if text.contains('.') {
                text.trim_end_matches('0').trim_end_matches('.')
            } else {
                &text
            };
            f.write_str(text)
        } else {
            let text = format!("{x:.5e}");
            match text.split_once('e') {
                Some((mantissa, exponent)) if mantissa.contains('.') => {
                    let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
                    write!(f, "{mantissa}e{exponent}")
                }
                _ => f.write_str(&text),
            }
        }
    }
}

/// A number exactly as it is (the shortest text that reads back as the
/// same `f64`), in exponent form below 1e-4 and from 1e6 on: for errors,
/// where a rounded value could hide why it was refused.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Exact(pub f64);

impl fmt::Display for Exact {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        if x.is_finite() && x != 0.0 && !(1e-4..1e6).contains(&x.abs()) {
            write!(f, "{x:e}")
        } else {
            write!(f, "{x}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_read_back_readably() {
        assert_eq!(Readable(1.0 / 30.0).to_string(), "0.0333333");
        assert_eq!(Readable(0.05).to_string(), "0.05");
        assert_eq!(Readable(3600.0).to_string(), "3600");
        assert_eq!(Readable(1e300).to_string(), "1e300");
        assert_eq!(Readable(1e-6).to_string(), "1e-6");
        assert_eq!(Readable(1.0 / 3600.0).to_string(), "0.000277778");
        assert_eq!(Readable(0.0).to_string(), "0");
        assert_eq!(Readable(f64::NAN).to_string(), "NaN");
        assert_eq!(Exact(1e300).to_string(), "1e300");
        assert_eq!(
            Exact(0.03333333333333333).to_string(),
            "0.03333333333333333"
        );
    }
}
