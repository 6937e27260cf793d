//! The parameter vocabulary in words: every choice a front end offers (command-line values,
//! Python keywords, JSON statistics) parses from and prints as the same names, defined once here.

use std::fmt;
use std::str::FromStr;

use crate::{BmCost, Error, PathCount, Preset, Search, Subpixel};

/// A choice among named values: its names, a line of help for each, parsing and printing.
pub trait Named: Copy + Sized + 'static {
    /// What the choice is, for messages (`"preset"`).
    const WHAT: &'static str;
    /// Every value, in the order front ends list them.
    const ALL: &'static [Self];
    /// The value's name (`"fast"`).
    fn name(self) -> &'static str;
    /// One line saying what the value does.
    fn help(self) -> &'static str;
}

/// Parses `text` as one of `T`'s names; the error lists them.
pub fn parse_named<T: Named>(text: &str) -> Result<T, Error> {
    T::ALL.iter().copied().find(|v| v.name() == text).ok_or_else(|| Error::InvalidParameter {
        name: T::WHAT,
        message: format!(
            "unknown value {text:?} (one of {})",
            T::ALL.iter().map(|v| v.name()).collect::<Vec<_>>().join(", ")
        ),
    })
}

macro_rules! named {
    ($ty:ident, $what:literal, [$($variant:ident => $name:literal, $help:literal;)+]) => {
        impl Named for $ty {
            const WHAT: &'static str = $what;
            const ALL: &'static [Self] = &[$($ty::$variant),+];
            fn name(self) -> &'static str {
                match self {
                    $($ty::$variant => $name,)+
                }
            }
            fn help(self) -> &'static str {
                match self {
                    $($ty::$variant => $help,)+
                }
            }
        }

        impl fmt::Display for $ty {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.write_str(self.name())
            }
        }

        impl FromStr for $ty {
            type Err = Error;
            fn from_str(text: &str) -> Result<Self, Error> {
                parse_named(text)
            }
        }

        #[cfg(feature = "serde")]
        impl serde::Serialize for $ty {
            fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
                serializer.serialize_str(self.name())
            }
        }

        #[cfg(feature = "serde")]
        impl<'de> serde::Deserialize<'de> for $ty {
            fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
                let text = <std::borrow::Cow<'de, str>>::deserialize(deserializer)?;
                parse_named(&text).map_err(serde::de::Error::custom)
            }
        }
    };
}

named!(Preset, "preset", [
    Fast => "fast", "3 path directions in a single pass (like OpenCV's SGBM_3WAY): the fastest";
    Balanced => "balanced", "8 paths (the default)";
    Accurate => "accurate", "balanced plus an edge-aware weighted median: fewer errors at depth edges, slower";
]);

named!(PathCount, "paths", [
    Four => "4", "4 path directions (3 in a single pass)";
    Eight => "8", "8 path directions (5 in a single pass)";
]);

named!(Subpixel, "subpixel", [
    None => "none", "integer disparities only";
    Parabola => "parabola", "a parabola through the three costs around the minimum";
    Equiangular => "equiangular", "two lines of equal and opposite slope (suits census/L1 costs)";
]);

named!(Search, "search", [
    Full => "full", "every pixel over the whole disparity range";
    Hierarchical => "hierarchical", "coarse to fine: each pixel in a band around a half-resolution match";
    Auto => "auto", "hierarchical from 256 disparities (128 from 2 megapixels), else full (the default)";
]);

named!(BmCost, "block-matching cost", [
    Sad => "sad", "sum of absolute differences on an x-Sobel prefiltered image";
    Census => "census", "Hamming distances of 5x5 census strings; robust to gain and bias changes";
]);

#[cfg(test)]
mod tests {
    use super::*;

    fn round_trip<T: Named + fmt::Display + FromStr<Err = Error> + PartialEq + fmt::Debug>() {
        for &value in T::ALL {
            assert_eq!(value.to_string().parse::<T>().unwrap(), value);
            assert!(!value.help().is_empty());
        }
    }

    #[test]
    fn every_name_parses_back_to_its_value() {
        round_trip::<Preset>();
        round_trip::<PathCount>();
        round_trip::<Subpixel>();
        round_trip::<BmCost>();
        round_trip::<Search>();
    }

    #[test]
    fn unknown_names_list_the_known_ones() {
        let err = "quick".parse::<Preset>().unwrap_err().to_string();
        assert_eq!(
            err,
            "invalid parameter preset: unknown value \"quick\" (one of fast, balanced, accurate)"
        );
    }
}
