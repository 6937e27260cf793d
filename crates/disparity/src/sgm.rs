//! Semi-Global Matching: census cost volume, path aggregation, winner-takes-all, checks.

use crate::aggregate::{aggregate_paths, P2Table, MAX_P2};
use crate::census::census_transform;
use crate::cost::hamming_cost_volume;
use crate::filter::median_3x3;
use crate::wta::{select_disparities, Selection};
use crate::{check_pair, DisparityMap, Error, GrayImage, Image, SgmParams};

/// Semi-Global Matching of a rectified pair (Hirschmüller 2008) with census costs.
///
/// Returns the left view's disparity map; NaN where no disparity in the range fits, or where the
/// uniqueness or left-right check rejects the match.
pub fn sgm(left: &GrayImage, right: &GrayImage, params: &SgmParams) -> Result<DisparityMap, Error> {
    check_pair(left, right)?;
    params.census.check()?;
    let (width, height) = left.size();
    if width < params.census.width || height < params.census.height {
        return Err(Error::ImageTooSmall {
            width,
            height,
            window_width: params.census.width,
            window_height: params.census.height,
        });
    }
    params.range.check(width)?;
    if params.p1 == 0 || params.p1 >= params.p2 || params.p2 > MAX_P2 {
        return Err(Error::InvalidParameter {
            name: "p1/p2",
            message: format!("need 0 < P1 < P2 <= {MAX_P2}, got P1 = {} and P2 = {}", params.p1, params.p2),
        });
    }
    if let Some(d) = params.lr_max_diff {
        if d.is_nan() || d < 0.0 {
            return Err(Error::InvalidParameter {
                name: "left-right max difference",
                message: format!("{d} must be a number >= 0"),
            });
        }
    }

    let nd = params.range.count();
    let census_bits = (params.census.width * params.census.height - 1) as u32;
    let mut census_left = Image::new(width, height, 0u64);
    let mut census_right = Image::new(width, height, 0u64);
    rayon::join(
        || census_transform(left, params.census, &mut census_left),
        || census_transform(right, params.census, &mut census_right),
    );

    let mut cost = vec![0u8; width * height * nd];
    hamming_cost_volume(&census_left, &census_right, params.range, census_bits, &mut cost);
    drop((census_left, census_right));

    let mut sum = vec![0u16; width * height * nd];
    let p2 = P2Table::new(params.p1, params.p2, params.p2_edge_scale);
    aggregate_paths(left, &cost, nd, params.paths, params.p1, &p2, &mut sum);
    drop(cost);

    let mut disparity = DisparityMap::new(width, height, f32::NAN);
    let selection = Selection {
        range: params.range,
        uniqueness_ratio: params.uniqueness_ratio,
        lr_max_diff: params.lr_max_diff,
        subpixel: params.subpixel,
    };
    select_disparities(&sum, width, nd, selection, &mut disparity);
    if params.median {
        disparity = median_3x3(&disparity);
    }
    Ok(disparity)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{DisparityRange, PathCount};

    fn texture(x: i64, y: i64) -> u16 {
        // A hash: every pixel differs from its neighbours, so every shift is unambiguous.
        let h = (x.wrapping_mul(0x9E37_79B9) ^ y.wrapping_mul(0x85EB_CA6B)).wrapping_mul(0xC2B2_AE35);
        ((h >> 16) & 0xffff) as u16
    }

    #[test]
    fn constant_shift_is_recovered_exactly() {
        for paths in [PathCount::Four, PathCount::Eight] {
            let left = GrayImage::from_fn(80, 40, |x, y| texture(x as i64, y as i64));
            let right = GrayImage::from_fn(80, 40, |x, y| texture(x as i64 + 7, y as i64));
            let params = SgmParams { range: DisparityRange::new(0, 24).unwrap(), paths, ..SgmParams::default() };
            let d = sgm(&left, &right, &params).unwrap();
            let mut good = 0;
            for y in 0..40 {
                // Away from the borders, where the census windows of both views are whole.
                for x in 12..75 {
                    let v = d.get(x, y);
                    assert!(v.is_nan() || (v - 7.0).abs() < 0.5, "({x},{y}): {v}");
                    good += usize::from(!v.is_nan());
                }
            }
            assert!(good > 63 * 40 * 95 / 100, "{paths:?}: only {good} valid");
        }
    }

    #[test]
    fn negative_minimum_disparity_is_supported() {
        let left = GrayImage::from_fn(60, 30, |x, y| texture(x as i64, y as i64));
        let right = GrayImage::from_fn(60, 30, |x, y| texture(x as i64 - 3, y as i64));
        let params = SgmParams { range: DisparityRange::new(-8, 8).unwrap(), ..SgmParams::default() };
        let d = sgm(&left, &right, &params).unwrap();
        assert!((d.get(30, 15) + 3.0).abs() < 0.5);
    }

    #[test]
    fn bad_input_is_rejected() {
        let a = GrayImage::new(40, 20, 0);
        let b = GrayImage::new(41, 20, 0);
        let p = SgmParams { range: DisparityRange { min: 0, max: 16 }, ..SgmParams::default() };
        assert!(matches!(sgm(&a, &b, &p), Err(Error::SizeMismatch { .. })));
        let wide = SgmParams { range: DisparityRange { min: 0, max: 64 }, ..p.clone() };
        assert!(matches!(sgm(&a, &a, &wide), Err(Error::RangeWiderThanImage { .. })));
        let empty = SgmParams { range: DisparityRange { min: 8, max: 8 }, ..p.clone() };
        assert!(matches!(sgm(&a, &a, &empty), Err(Error::EmptyRange { .. })));
        let pen = SgmParams { p1: 50, p2: 10, ..p.clone() };
        assert!(matches!(sgm(&a, &a, &pen), Err(Error::InvalidParameter { .. })));
        let tiny = GrayImage::new(5, 5, 0);
        let small = SgmParams { range: DisparityRange { min: 0, max: 2 }, ..p };
        assert!(matches!(sgm(&tiny, &tiny, &small), Err(Error::ImageTooSmall { .. })));
    }
}
