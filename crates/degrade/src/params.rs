//! The degradation parameters, their ranges, and the `key=value,...` spec syntax.

use std::fmt;
use std::str::FromStr;

use crate::Error;

/// What to do to one view. Every field is optional: `None` leaves that aspect unchanged, so
/// `Degradation::default()` is the identity.
///
/// Spec syntax ([`FromStr`] / [`fmt::Display`]): a comma list of `key=value`, e.g.
/// `gain=1.6,gamma=2,vignette=0.4,noise=6,jpeg=50,blur=1.5,vshift=1,rotate=0.1,bias=30`;
/// `none` or an empty string is the identity.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Degradation {
    /// Global gain `g`: `v' = clip(g·v)`. Range (0, 4].
    pub gain: Option<f32>,
    /// Gamma `γ`: `v' = v^γ` on [0, 1]. Range [0.2, 5].
    pub gamma: Option<f32>,
    /// Bias in grey levels of the 8-bit scale (whatever the bit depth): `v' = clip(v + b/255)`.
    /// Range [-255, 255].
    pub bias: Option<f32>,
    /// Vignetting fall-off `f`: multiplies by `1 − f·(r/r_corner)²`, `r` the distance from the
    /// image centre, so the corners get exactly `1 − f`. Range [0, 1].
    pub vignette: Option<f32>,
    /// Gaussian noise σ in grey levels of the 8-bit scale, independent per pixel and channel.
    /// Range [0, 64].
    pub noise: Option<f32>,
    /// JPEG quality (encode then decode at 8 bits). Range 1..=100.
    pub jpeg: Option<u8>,
    /// Defocus: Gaussian blur σ in pixels. Range [0, 10].
    pub blur: Option<f32>,
    /// Vertical shift in pixels, sub-pixel; positive moves the content down. Range [-16, 16].
    pub vshift: Option<f32>,
    /// Rotation in degrees about the image centre; positive turns the content clockwise as
    /// displayed (y points down). Range [-5, 5].
    pub rotate: Option<f32>,
}

/// The spec keys, in the order [`fmt::Display`] writes them.
pub const KEYS: [&str; 9] =
    ["gain", "gamma", "bias", "vignette", "noise", "jpeg", "blur", "vshift", "rotate"];

impl Degradation {
    /// True when no field is set: [`crate::degrade`] then returns the image unchanged.
    pub fn is_identity(&self) -> bool {
        *self == Degradation::default()
    }

    /// `self`, with the fields it leaves unset taken from `base` (a per-view spec over a spec
    /// for both views).
    pub fn over(&self, base: &Degradation) -> Degradation {
        Degradation {
            gain: self.gain.or(base.gain),
            gamma: self.gamma.or(base.gamma),
            bias: self.bias.or(base.bias),
            vignette: self.vignette.or(base.vignette),
            noise: self.noise.or(base.noise),
            jpeg: self.jpeg.or(base.jpeg),
            blur: self.blur.or(base.blur),
            vshift: self.vshift.or(base.vshift),
            rotate: self.rotate.or(base.rotate),
        }
    }

    /// Checks every set field against its range; the error names the parameter.
    pub fn validate(&self) -> Result<(), Error> {
        check("gain", self.gain, 0.0, 4.0, false)?;
        check("gamma", self.gamma, 0.2, 5.0, true)?;
        check("bias", self.bias, -255.0, 255.0, true)?;
        check("vignette", self.vignette, 0.0, 1.0, true)?;
        check("noise", self.noise, 0.0, 64.0, true)?;
        if let Some(q) = self.jpeg {
            if !(1..=100).contains(&q) {
                return Err(Error::Param {
                    name: "jpeg",
                    message: format!("quality {q} is outside 1..=100"),
                });
            }
        }
        check("blur", self.blur, 0.0, 10.0, true)?;
        check("vshift", self.vshift, -16.0, 16.0, true)?;
        check("rotate", self.rotate, -5.0, 5.0, true)?;
        Ok(())
    }

    fn set(&mut self, key: &str, value: &str) -> Result<(), Error> {
        let float = |name: &'static str| -> Result<Option<f32>, Error> {
            match value.trim().parse::<f32>() {
                Ok(v) if v.is_finite() => Ok(Some(v)),
                _ => Err(Error::Param { name, message: format!("{value:?} is not a finite number") }),
            }
        };
        match key {
            "gain" => self.gain = float("gain")?,
            "gamma" => self.gamma = float("gamma")?,
            "bias" => self.bias = float("bias")?,
            "vignette" => self.vignette = float("vignette")?,
            "noise" => self.noise = float("noise")?,
            "blur" => self.blur = float("blur")?,
            "vshift" => self.vshift = float("vshift")?,
            "rotate" => self.rotate = float("rotate")?,
            "jpeg" => {
                let q = value.trim().parse::<u8>().map_err(|_| Error::Param {
                    name: "jpeg",
                    message: format!("{value:?} is not a quality 1..=100"),
                })?;
                self.jpeg = Some(q);
            }
            _ => return Err(Error::UnknownKey { key: key.to_string(), known: KEYS.join(", ") }),
        }
        Ok(())
    }
}

/// `value` within `[lo, hi]` (or `(lo, hi]` when `lo_inclusive` is false).
fn check(name: &'static str, value: Option<f32>, lo: f32, hi: f32, lo_inclusive: bool) -> Result<(), Error> {
    let Some(v) = value else { return Ok(()) };
    let above_lo = if lo_inclusive { v >= lo } else { v > lo };
    if v.is_finite() && above_lo && v <= hi {
        return Ok(());
    }
    let open = if lo_inclusive { '[' } else { '(' };
    Err(Error::Param { name, message: format!("{v} is outside {open}{lo}, {hi}]") })
}

impl FromStr for Degradation {
    type Err = Error;

    /// Parses and validates a spec; a key given twice is an error.
    fn from_str(spec: &str) -> Result<Self, Error> {
        let mut d = Degradation::default();
        let spec = spec.trim();
        if spec.is_empty() || spec == "none" {
            return Ok(d);
        }
        let mut seen = Vec::new();
        for item in spec.split(',') {
            let item = item.trim();
            let Some((key, value)) = item.split_once('=') else {
                return Err(Error::Syntax(format!("{item:?} is not key=value")));
            };
            let key = key.trim();
            if seen.contains(&key) {
                return Err(Error::Syntax(format!("{key} given twice")));
            }
            seen.push(key);
            d.set(key, value)?;
        }
        d.validate()?;
        Ok(d)
    }
}

impl fmt::Display for Degradation {
    /// The spec that parses back to `self` (`none` for the identity).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let floats = [
            ("gain", self.gain),
            ("gamma", self.gamma),
            ("bias", self.bias),
            ("vignette", self.vignette),
            ("noise", self.noise),
            ("jpeg", self.jpeg.map(f32::from)),
            ("blur", self.blur),
            ("vshift", self.vshift),
            ("rotate", self.rotate),
        ];
        let parts: Vec<String> = floats.iter().filter_map(|(k, v)| v.map(|v| format!("{k}={v}"))).collect();
        if parts.is_empty() {
            f.write_str("none")
        } else {
            f.write_str(&parts.join(","))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_every_key_and_prints_back() {
        let spec = "gain=1.6,gamma=2,bias=-30,vignette=0.4,noise=6,jpeg=50,blur=1.5,vshift=-0.5,rotate=0.1";
        let d: Degradation = spec.parse().unwrap();
        assert_eq!(d.gain, Some(1.6));
        assert_eq!(d.bias, Some(-30.0));
        assert_eq!(d.jpeg, Some(50));
        assert_eq!(d.vshift, Some(-0.5));
        assert_eq!(d.to_string(), spec);
        assert_eq!(d.to_string().parse::<Degradation>().unwrap(), d);
    }

    #[test]
    fn empty_and_none_are_identity() {
        assert!("".parse::<Degradation>().unwrap().is_identity());
        assert!("none".parse::<Degradation>().unwrap().is_identity());
        assert_eq!(Degradation::default().to_string(), "none");
    }

    #[test]
    fn errors_name_the_parameter() {
        let msg = |s: &str| s.parse::<Degradation>().unwrap_err().to_string();
        assert!(msg("gain=0").contains("gain"), "{}", msg("gain=0"));
        assert!(msg("gain=abc").starts_with("gain: "), "{}", msg("gain=abc"));
        assert!(msg("jpeg=0").starts_with("jpeg: "), "{}", msg("jpeg=0"));
        assert!(msg("jpeg=101").starts_with("jpeg: "));
        assert!(msg("vignette=1.5").starts_with("vignette: "));
        assert!(msg("noise=-1").starts_with("noise: "));
        assert!(msg("rotate=nan").starts_with("rotate: "));
        assert!(msg("sharpen=2").contains("sharpen"));
        assert!(msg("gain").contains("key=value"));
        assert!(msg("gain=1,gain=2").contains("twice"));
    }

    #[test]
    fn per_view_spec_overrides_both() {
        let both: Degradation = "noise=6,gain=0.8".parse().unwrap();
        let right: Degradation = "gain=1.2".parse().unwrap();
        let d = right.over(&both);
        assert_eq!((d.gain, d.noise), (Some(1.2), Some(6.0)));
    }
}
