//! Post-filters on a finished disparity map.

use rayon::prelude::*;

use crate::DisparityMap;

/// 3×3 median over the valid (non-NaN) disparities around each valid pixel; invalid pixels stay
/// invalid. Removes isolated wrong matches and smooths subpixel noise without blurring edges.
pub(crate) fn median_3x3(disparity: &DisparityMap) -> DisparityMap {
    let (width, height) = disparity.size();
    let mut out = disparity.clone();
    out.as_mut_slice().par_chunks_mut(width.max(1)).enumerate().for_each(|(y, row)| {
        let mut window = [0f32; 9];
        for (x, o) in row.iter_mut().enumerate() {
            if o.is_nan() {
                continue;
            }
            let mut n = 0;
            for yy in y.saturating_sub(1)..(y + 2).min(height) {
                for xx in x.saturating_sub(1)..(x + 2).min(width) {
                    let v = disparity.get(xx, yy);
                    if !v.is_nan() {
                        window[n] = v;
                        n += 1;
                    }
                }
            }
            let w = &mut window[..n];
            w.sort_unstable_by(f32::total_cmp);
            *o = if n % 2 == 1 { w[n / 2] } else { 0.5 * (w[n / 2 - 1] + w[n / 2]) };
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn median_removes_an_outlier_and_keeps_holes() {
        let mut d = DisparityMap::new(5, 5, 10.0);
        d.set(2, 2, 40.0);
        d.set(0, 0, f32::NAN);
        let m = median_3x3(&d);
        assert_eq!(m.get(2, 2), 10.0);
        assert!(m.get(0, 0).is_nan());
        assert_eq!(m.get(4, 4), 10.0);
    }
}
