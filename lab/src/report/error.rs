//! The error figures of `cssm report error`: a method's image against the path tracer's, as
//! plain functions over linear radiance (`[r, g, b, a]` per pixel, row-major; alpha is
//! ignored) and, for FLIP, over the tone-mapped 8-bit images.
//!
//! **Which pixels count**: every pixel of the image. A pixel where neither image sees a surface
//! is black in both and adds nothing to any sum; telling "no surface" from "a surface the
//! indirect light does not reach" would need the G-buffer, and with `--component indirect` a
//! test on the radiance alone would drop exactly the dark pixels the leak measures.
//!
//! - [`relative_rmse`]: `sqrt(sum |m - r|^2 / sum |r|^2)` over the rgb channels of every pixel;
//! - [`mean_bias`]: `sum lum(m) / sum lum(r) - 1` (Rec. 709 luminance, [`luminance`]);
//! - [`leak`]: the light a method puts where the ground truth is dark: over the *mask* of pixels
//!   whose reference luminance is below half the median of the nonzero reference luminances,
//!   `sum max(0, lum(m) - lum(r)) / sum lum(r)`;
//! - [`mean_flip`]: mean FLIP (Andersson et al. 2020, `nv-flip`) of the tone-mapped images;
//! - [`noise_floor`]: the relative RMSE the reference itself has against the converged image,
//!   estimated from two independent halves of its paths.
//!
//! A figure whose denominator is zero (a black reference) is `None`.

/// Rec. 709 luminance of linear rgb.
pub fn luminance(c: &[f32; 4]) -> f64 {
    0.2126 * c[0] as f64 + 0.7152 * c[1] as f64 + 0.0722 * c[2] as f64
}

fn same_size(method: &[[f32; 4]], reference: &[[f32; 4]]) {
    assert_eq!(
        method.len(),
        reference.len(),
        "the method's and the reference's images differ in size"
    );
}

/// Relative RMSE `sqrt(sum |m - r|^2 / sum |r|^2)`, the sums over the rgb channels of every
/// pixel; `None` when the reference is black.
///
/// # Panics
/// When the images differ in size.
pub fn relative_rmse(method: &[[f32; 4]], reference: &[[f32; 4]]) -> Option<f64> {
    same_size(method, reference);
    let (mut err, mut norm) = (0.0f64, 0.0f64);
    for (m, r) in method.iter().zip(reference) {
        for c in 0..3 {
            let d = m[c] as f64 - r[c] as f64;
            err += d * d;
            norm += r[c] as f64 * r[c] as f64;
        }
    }
    (norm > 0.0).then(|| (err / norm).sqrt())
}

/// Mean relative bias `sum lum(m) / sum lum(r) - 1`: positive where the method is brighter
/// overall; `None` when the reference is black.
///
/// # Panics
/// When the images differ in size.
pub fn mean_bias(method: &[[f32; 4]], reference: &[[f32; 4]]) -> Option<f64> {
    same_size(method, reference);
    let m: f64 = method.iter().map(luminance).sum();
    let r: f64 = reference.iter().map(luminance).sum();
    (r > 0.0).then(|| m / r - 1.0)
}

/// Light leaking into the ground truth's (indirect) shadows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leak {
    /// `sum_mask max(0, lum(m) - lum(r)) / sum_mask lum(r)`; `None` when the mask is empty or
    /// black in the reference.
    pub leak: Option<f64>,
    /// Pixels in the mask.
    pub mask_pixels: usize,
}

/// The pixels whose reference luminance is below half the median of the nonzero reference
/// luminances (the ground truth's dark places), as a flag per pixel; none when the reference
/// is black.
pub fn dark_mask(reference: &[[f32; 4]]) -> Vec<bool> {
    let lum: Vec<f64> = reference.iter().map(luminance).collect();
    let mut nonzero: Vec<f64> = lum.iter().copied().filter(|&l| l > 0.0).collect();
    if nonzero.is_empty() {
        return vec![false; lum.len()];
    }
    nonzero.sort_by(f64::total_cmp);
    let n = nonzero.len();
    let median = if n % 2 == 1 {
        nonzero[n / 2]
    } else {
        0.5 * (nonzero[n / 2 - 1] + nonzero[n / 2])
    };
    lum.iter().map(|&l| l < 0.5 * median).collect()
}

/// The light the method adds where the ground truth is dark ([`dark_mask`]), relative to the
/// reference's light there: `sum_mask max(0, lum(m) - lum(r)) / sum_mask lum(r)`. Light
/// missing elsewhere does not offset it.
///
/// # Panics
/// When the images differ in size.
pub fn leak(method: &[[f32; 4]], reference: &[[f32; 4]]) -> Leak {
    same_size(method, reference);
    let mask = dark_mask(reference);
    let (mut excess, mut dark, mut count) = (0.0f64, 0.0f64, 0);
    for ((m, r), _) in method
        .iter()
        .zip(reference)
        .zip(&mask)
        .filter(|(_, inside)| **inside)
    {
        let (lm, lr) = (luminance(m), luminance(r));
        excess += (lm - lr).max(0.0);
        dark += lr;
        count += 1;
    }
    Leak {
        leak: (dark > 0.0).then(|| excess / dark),
        mask_pixels: count,
    }
}

/// The reference's own noise: the relative RMSE its image of `n1 + n2` paths per pixel has
/// against the converged image, estimated from its two independent parts, `half1` of `n1` paths
/// and `half2` of `n2` (same options, other seeds; the reference is `(n1 half1 + n2 half2) / N`).
///
/// Per channel the variance of the difference is `s^2 (1/n1 + 1/n2)` and that of the whole
/// `s^2 / N`, so the whole's squared error is the difference's times `n1 n2 / N^2` (a quarter for
/// equal halves). A method equal to the converged image would show this relative RMSE against
/// the reference; a method with no error of its own and `N` paths of its own (`reference` as a
/// method) about `sqrt(2)` times it. `None` when a part has no paths or the reference is black.
///
/// # Panics
/// When the images differ in size.
pub fn noise_floor(half1: &[[f32; 4]], n1: u32, half2: &[[f32; 4]], n2: u32) -> Option<f64> {
    same_size(half1, half2);
    if n1 == 0 || n2 == 0 {
        return None;
    }
    let (w1, w2) = (n1 as f64, n2 as f64);
    let n = w1 + w2;
    let (mut diff, mut norm) = (0.0f64, 0.0f64);
    for (a, b) in half1.iter().zip(half2) {
        for c in 0..3 {
            let (a, b) = (a[c] as f64, b[c] as f64);
            diff += (a - b) * (a - b);
            let whole = (w1 * a + w2 * b) / n;
            norm += whole * whole;
        }
    }
    (norm > 0.0).then(|| (diff * w1 * w2 / (n * n) / norm).sqrt())
}

/// `(n1 half1 + n2 half2) / (n1 + n2)` per pixel: the image of all the paths.
///
/// # Panics
/// When the images differ in size or both counts are 0.
pub fn combine(half1: &[[f32; 4]], n1: u32, half2: &[[f32; 4]], n2: u32) -> Vec<[f32; 4]> {
    same_size(half1, half2);
    assert!(n1 + n2 > 0, "no paths to combine");
    let (w1, w2) = (n1 as f64, n2 as f64);
    let n = w1 + w2;
    half1
        .iter()
        .zip(half2)
        .map(|(a, b)| std::array::from_fn(|c| ((w1 * a[c] as f64 + w2 * b[c] as f64) / n) as f32))
        .collect()
}

/// FLIP (Andersson et al. 2020, `nv-flip`) of `test` against `reference`, both tone-mapped RGBA8
/// images of `width` x `height` (alpha is ignored), at nv-flip's default viewing distance: the
/// per-pixel error map (0 to 1).
///
/// # Panics
/// When a buffer is not `width * height * 4` bytes.
fn flip_error(width: u32, height: u32, reference: &[u8], test: &[u8]) -> nv_flip::FlipImageFloat {
    let rgb = |rgba: &[u8]| -> Vec<u8> {
        assert_eq!(
            rgba.len(),
            width as usize * height as usize * 4,
            "not an RGBA8 image of {width}x{height}"
        );
        rgba.chunks_exact(4)
            .flat_map(|p| [p[0], p[1], p[2]])
            .collect()
    };
    let reference = nv_flip::FlipImageRgb8::with_data(width, height, &rgb(reference));
    let test = nv_flip::FlipImageRgb8::with_data(width, height, &rgb(test));
    nv_flip::flip(reference, test, nv_flip::DEFAULT_PIXELS_PER_DEGREE)
}

/// Mean FLIP error (0 to 1) of `test` against `reference`, both tone-mapped RGBA8 images of
/// `width` x `height` (alpha is ignored), at nv-flip's default viewing distance.
///
/// # Panics
/// When a buffer is not `width * height * 4` bytes.
pub fn mean_flip(width: u32, height: u32, reference: &[u8], test: &[u8]) -> f32 {
    nv_flip::FlipPool::from_image(&flip_error(width, height, reference, test)).mean()
}

/// The FLIP error map of `test` against `reference` (as [`mean_flip`]) in the magma colour map
/// of the FLIP paper (black: no visible difference; yellow: the largest), RGBA8.
///
/// # Panics
/// When a buffer is not `width * height * 4` bytes.
pub fn flip_map(width: u32, height: u32, reference: &[u8], test: &[u8]) -> Vec<u8> {
    flip_error(width, height, reference, test)
        .apply_color_lut(&nv_flip::magma_lut())
        .to_vec()
        .chunks_exact(3)
        .flat_map(|p| [p[0], p[1], p[2], 255])
        .collect()
}

/// The reference's own noise in each figure, from its two independent halves: what a method
/// equal to the converged image would measure against it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ReferenceNoise {
    /// [`noise_floor`]: its relative RMSE against the converged image.
    pub relative_rmse: Option<f64>,
    /// Mean FLIP of the whole against its first half. The difference `whole - half1` is
    /// `n2 / N (half2 - half1)`, of the whole's own variance for equal halves: the FLIP an image
    /// as far from the reference as the reference is from the converged one would show.
    pub flip: Option<f32>,
    /// The standard deviation of the reference's total luminance relative to it, the noise of
    /// [`mean_bias`]: `|L1 - L2| sqrt(n1 n2) / N / L` (the halves' mean luminances `L1`, `L2`,
    /// the whole's `L`), a one-sample estimate.
    pub bias: Option<f64>,
}

impl ReferenceNoise {
    /// The noise of the reference of `size` made of `half1` (`n1` paths per pixel) and `half2`
    /// (`n2`), whose whole and first half are tone-mapped to `display` (`whole`, `half1`).
    ///
    /// # Panics
    /// When the images differ in size.
    pub fn measure(
        size: (u32, u32),
        half1: (&[[f32; 4]], u32),
        half2: (&[[f32; 4]], u32),
        display: (&[u8], &[u8]),
    ) -> Self {
        let (n1, n2) = (half1.1, half2.1);
        let relative_rmse = noise_floor(half1.0, n1, half2.0, n2);
        let flip = (n1 > 0 && n2 > 0).then(|| mean_flip(size.0, size.1, display.0, display.1));
        let lum = |image: &[[f32; 4]]| image.iter().map(luminance).sum::<f64>();
        let (l1, l2) = (lum(half1.0), lum(half2.0));
        let n = (n1 + n2) as f64;
        let whole = (n1 as f64 * l1 + n2 as f64 * l2) / n;
        let bias = (n1 > 0 && n2 > 0 && whole > 0.0)
            .then(|| (l1 - l2).abs() * (n1 as f64 * n2 as f64).sqrt() / n / whole);
        Self {
            relative_rmse,
            flip,
            bias,
        }
    }
}

/// The relative RMSE a method has against the converged image, the reference's noise taken
/// out: `sqrt(max(0, e^2 - f^2))` for the measured relative RMSE `e` and the noise floor `f`.
/// The reference's noise is independent of the method's image and of mean zero, so the squared
/// error against the reference is the squared error against the converged image plus the
/// reference's own, on average. `None` without both.
///
/// ```
/// use cssm_lab::report::error::without_noise;
/// assert_eq!(without_noise(Some(0.5), Some(0.3)), Some(0.4));
/// assert_eq!(without_noise(Some(0.1), Some(0.3)), Some(0.0));
/// ```
pub fn without_noise(relative_rmse: Option<f64>, floor: Option<f64>) -> Option<f64> {
    let (e, f) = (relative_rmse?, floor?);
    Some((e * e - f * f).max(0.0).sqrt())
}

/// The share of the squared relative RMSE `e` that the reference's noise floor `f` accounts
/// for, `min(1, f^2 / e^2)`; `None` without both or when `e` is 0.
///
/// ```
/// use cssm_lab::report::error::noise_share;
/// assert_eq!(noise_share(Some(0.5), Some(0.25)), Some(0.25));
/// ```
pub fn noise_share(relative_rmse: Option<f64>, floor: Option<f64>) -> Option<f64> {
    let (e, f) = (relative_rmse?, floor?);
    (e > 0.0).then(|| (f * f / (e * e)).min(1.0))
}

/// Every figure of one method against the reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Figures {
    /// [`relative_rmse`].
    pub relative_rmse: Option<f64>,
    /// [`mean_bias`].
    pub bias: Option<f64>,
    /// [`leak`].
    pub leak: Leak,
    /// [`mean_flip`].
    pub mean_flip: f32,
}

impl Figures {
    /// The figures of `method` against `reference`: linear radiance, and the tone-mapped RGBA8
    /// images of `width` x `height`.
    pub fn measure(
        width: u32,
        height: u32,
        method: (&[[f32; 4]], &[u8]),
        reference: (&[[f32; 4]], &[u8]),
    ) -> Self {
        Self {
            relative_rmse: relative_rmse(method.0, reference.0),
            bias: mean_bias(method.0, reference.0),
            leak: leak(method.0, reference.0),
            mean_flip: mean_flip(width, height, reference.1, method.1),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grey(v: f32) -> [f32; 4] {
        [v, v, v, 1.0]
    }

    /// A reference with bright and dark pixels (luminance equals the grey value).
    fn reference() -> Vec<[f32; 4]> {
        [1.0, 2.0, 3.0, 4.0, 0.1, 0.2, 0.0, 5.0]
            .into_iter()
            .map(grey)
            .collect()
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-6
    }

    #[test]
    fn identical_images_have_no_error() {
        let r = reference();
        assert_eq!(relative_rmse(&r, &r), Some(0.0));
        assert_eq!(mean_bias(&r, &r), Some(0.0));
        let l = leak(&r, &r);
        assert_eq!(l.leak, Some(0.0));
        assert_eq!(l.mask_pixels, 3);
        let bytes = vec![128u8; 4 * r.len()];
        assert_eq!(mean_flip(4, 2, &bytes, &bytes), 0.0);
    }

    #[test]
    fn a_uniformly_brighter_image() {
        let r = reference();
        let m: Vec<_> = r.iter().map(|c| c.map(|v| 1.1 * v)).collect();
        assert!(close(mean_bias(&m, &r).unwrap(), 0.1));
        assert!(close(relative_rmse(&m, &r).unwrap(), 0.1));
        // 10% more everywhere is 10% more in the dark pixels too.
        assert!(close(leak(&m, &r).leak.unwrap(), 0.1));
        let dark: Vec<_> = r.iter().map(|c| c.map(|v| 0.5 * v)).collect();
        assert!(close(mean_bias(&dark, &r).unwrap(), -0.5));
        assert_eq!(leak(&dark, &r).leak, Some(0.0), "darker is no leak");
    }

    #[test]
    fn rmse_is_over_the_channels() {
        let r = vec![[3.0, 0.0, 4.0, 1.0]];
        let m = vec![[0.0, 0.0, 4.0, 7.0]];
        // |m - r|^2 = 9, |r|^2 = 25; alpha ignored.
        assert!(close(relative_rmse(&m, &r).unwrap(), 0.6));
        let black = vec![[0.0; 4]];
        assert_eq!(relative_rmse(&m, &black), None);
        assert_eq!(mean_bias(&m, &black), None);
    }

    #[test]
    fn the_mask_is_below_half_the_median_of_the_nonzero() {
        // Nonzero luminances 0.1 0.2 1 2 3 4 5: median 2, so the mask is < 1: 0.1, 0.2 and the
        // black pixel.
        let mask = dark_mask(&reference());
        assert_eq!(
            mask,
            [false, false, false, false, true, true, true, false].to_vec()
        );
        // An even count takes the mean of the middle two: 1 2 3 4, median 2.5, mask < 1.25.
        let even: Vec<_> = [1.0, 2.0, 3.0, 4.0].into_iter().map(grey).collect();
        assert_eq!(dark_mask(&even), [true, false, false, false].to_vec());
        assert_eq!(dark_mask(&[grey(0.0); 3]), [false; 3].to_vec());
    }

    #[test]
    fn leak_counts_only_the_masked_pixels() {
        let r = reference();
        let mut m = r.clone();
        // Much more light on bright pixels: no leak.
        m[0] = grey(10.0);
        m[7] = grey(50.0);
        let l = leak(&m, &r);
        assert_eq!((l.leak, l.mask_pixels), (Some(0.0), 3));
        // 0.3 more on the dark 0.1 pixel and 0.2 less on the dark 0.2 one: the excess alone
        // counts, over the mask's 0.3.
        m[4] = grey(0.4);
        m[5] = grey(0.0);
        assert!(close(leak(&m, &r).leak.unwrap(), 1.0));
        // Light on the black pixel counts as well.
        m[6] = grey(0.3);
        assert!(close(leak(&m, &r).leak.unwrap(), 2.0));
        assert_eq!(leak(&m, &[grey(0.0); 8]).leak, None);
    }

    #[test]
    fn noise_floor_from_two_halves() {
        let r = reference();
        // Halves r + e and r - e of equal counts: the whole is r, its error e.
        let e = 0.05f32;
        let h1: Vec<_> = r.iter().map(|c| c.map(|v| v + e)).collect();
        let h2: Vec<_> = r.iter().map(|c| c.map(|v| v - e)).collect();
        let whole = combine(&h1, 8, &h2, 8);
        for (a, b) in whole.iter().zip(&r) {
            assert!((a[0] - b[0]).abs() < 1e-6);
        }
        let norm: f64 = r.iter().map(|c| 3.0 * (c[0] as f64).powi(2)).sum();
        let expected = (3.0 * 8.0 * (e as f64).powi(2) / norm).sqrt();
        let floor = noise_floor(&h1, 8, &h2, 8).unwrap();
        assert!(
            (floor - expected).abs() < 1e-6 * expected.max(1.0),
            "{floor}"
        );
        // Identical halves: no noise; a part of no paths: no estimate.
        assert_eq!(noise_floor(&r, 4, &r, 4), Some(0.0));
        assert_eq!(noise_floor(&r, 0, &r, 4), None);
        // Unequal halves weight the whole.
        let w = combine(&[grey(1.0)], 1, &[grey(4.0)], 3);
        assert!((w[0][0] - 3.25).abs() < 1e-6);
    }

    #[test]
    fn noise_floor_matches_the_error_of_random_images() {
        // Pixels of a known value plus independent noise per path: the estimate from two halves
        // comes close to the whole's actual error against the truth.
        let mut rng = cssm_raycast::SplitMix64(7);
        let truth: Vec<[f32; 4]> = (0..4000).map(|i| grey(1.0 + (i % 5) as f32)).collect();
        let mut render = |n: u32| -> Vec<[f32; 4]> {
            truth
                .iter()
                .map(|t| {
                    let mean = (0..n).map(|_| rng.next_f64() as f32 - 0.5).sum::<f32>() / n as f32;
                    t.map(|v| v + mean)
                })
                .collect()
        };
        let (h1, h2) = (render(8), render(8));
        let floor = noise_floor(&h1, 8, &h2, 8).unwrap();
        let actual = relative_rmse(&combine(&h1, 8, &h2, 8), &truth).unwrap();
        assert!((floor / actual - 1.0).abs() < 0.1, "{floor} vs {actual}");
    }

    #[test]
    fn reference_noise_from_halves() {
        let r = reference();
        let e = 0.05f32;
        let h1: Vec<_> = r.iter().map(|c| c.map(|v| v + e)).collect();
        let h2: Vec<_> = r.iter().map(|c| c.map(|v| v - e)).collect();
        let bytes = |v: u8| vec![v; 4 * r.len()];
        let noise = ReferenceNoise::measure((4, 2), (&h1, 8), (&h2, 8), (&bytes(9), &bytes(9)));
        assert_eq!(noise.relative_rmse, noise_floor(&h1, 8, &h2, 8));
        assert_eq!(noise.flip, Some(0.0));
        // Luminance sums L1 = L + 8e, L2 = L - 8e over 8 pixels: |L1 - L2| / 2 / L.
        let l: f64 = r.iter().map(luminance).sum();
        let expected = 16.0 * e as f64 / 2.0 / l;
        assert!((noise.bias.unwrap() - expected).abs() < 1e-6, "{noise:?}");
        // Halves that agree have no noise; a half of no paths gives no estimate.
        let quiet = ReferenceNoise::measure((4, 2), (&r, 4), (&r, 4), (&bytes(9), &bytes(9)));
        assert_eq!((quiet.relative_rmse, quiet.bias), (Some(0.0), Some(0.0)));
        let none = ReferenceNoise::measure((4, 2), (&r, 4), (&r, 0), (&bytes(9), &bytes(9)));
        assert_eq!(none, ReferenceNoise::default());
    }

    #[test]
    fn noise_comes_out_in_quadrature() {
        // A method 0.3 from the truth against a reference with floor 0.4 measures 0.5.
        assert!((without_noise(Some(0.5), Some(0.4)).unwrap() - 0.3).abs() < 1e-12);
        assert!((noise_share(Some(0.5), Some(0.4)).unwrap() - 0.64).abs() < 1e-12);
        assert_eq!(noise_share(Some(0.1), Some(0.4)), Some(1.0));
        assert_eq!(noise_share(Some(0.0), Some(0.4)), None);
        assert_eq!(without_noise(None, Some(0.4)), None);
    }

    #[test]
    fn flip_map_is_black_where_equal() {
        let a = vec![40u8; 16 * 12 * 4];
        let mut b = a.clone();
        for p in b.chunks_exact_mut(4).take(16) {
            p[..3].copy_from_slice(&[250, 250, 250]);
        }
        let map = flip_map(16, 12, &a, &a);
        assert_eq!(map.len(), 16 * 12 * 4);
        let black = &map[..4];
        assert!(
            map.chunks_exact(4).all(|p| p == black),
            "no difference: one colour"
        );
        let map = flip_map(16, 12, &a, &b);
        // The changed first row is brighter in the map than the untouched bottom row.
        let lum = |p: &[u8]| p[0] as u32 + p[1] as u32 + p[2] as u32;
        assert!(
            lum(&map[..4]) > lum(&map[map.len() - 4..]),
            "{:?}",
            &map[..8]
        );
    }

    #[test]
    fn flip_sees_a_difference() {
        let a = vec![40u8; 16 * 12 * 4];
        let mut b = a.clone();
        for p in b.chunks_exact_mut(4).take(96) {
            p[..3].copy_from_slice(&[220, 220, 220]);
        }
        let f = mean_flip(16, 12, &a, &b);
        assert!(f > 0.1 && f < 1.0, "{f}");
    }
}
