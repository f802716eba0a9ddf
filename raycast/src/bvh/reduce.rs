//! A ray's hits, met in any order, reduced to its first hit, whether that surface faces the
//! origin, and its second hit (dual depth layers, §3.2): streamed by [`HitReducer`] as a
//! traversal or a rasteriser meets them, and defined by [`reduce_hits`] over the full list.

use super::FrontHit;

/// Hits farther than this many beyond the first may still join the first surface's cluster in
/// [`HitReducer`] without overflowing it (a ray through a vertex meets every triangle around it).
const CLUSTER: usize = 3;

/// Reduces the hits of one ray, met in *any* order, to its first hit, whether the first surface
/// faces the origin and the second hit: exactly [`reduce_hits`] over the same hits, streamed.
///
/// The answer must not depend on the order the hits arrive in: the BVH meets them in its
/// traversal's order, the bake's rasteriser triangle by triangle, and both must write the same
/// cube maps. Hits within `separation` of the first are one surface (a ray through a shared
/// edge meets both triangles at one `t`), but which hits those are is only known once the first
/// is: so the reducer keeps every hit within `separation` of the current first (up to
/// three of them; more sets [`HitReducer::overflowed`] and the caller reduces the full
/// list with [`reduce_hits`]), and re-sorts them when a nearer first arrives.
///
/// ```
/// use cssm_raycast::{HitReducer, reduce_hits};
/// let hits = [(3.0, true), (1.0, false), (1.0005, true), (2.0, false)];
/// let mut r = HitReducer::default();
/// for &(t, faces) in hits.iter().rev() {
///     r.add(t, faces, 1e-3);
/// }
/// let expected = reduce_hits(&hits, 1e-3);
/// assert_eq!((r.first(), r.first_faces(), r.second()), (1.0, true, 3.0));
/// assert_eq!(r.hit(), expected);
/// ```
#[derive(Clone, Copy, Debug)]
pub struct HitReducer {
    first: f32,
    second: f32,
    /// Other hits within the separation of `first`.
    cluster: [f32; CLUSTER],
    /// Bit `i` for `cluster[i]` facing the origin, bit `CLUSTER` for `first`.
    faces: u8,
    len: u8,
    overflowed: bool,
}

impl Default for HitReducer {
    fn default() -> Self {
        Self {
            first: f32::INFINITY,
            second: f32::INFINITY,
            cluster: [f32::INFINITY; CLUSTER],
            faces: 0,
            len: 0,
            overflowed: false,
        }
    }
}

/// `t` lies more than `separation` beyond `first`: another surface. Monotone in `first`, so a
/// hit beyond the first stays beyond it when a nearer first arrives.
#[inline]
fn beyond(t: f32, first: f32, separation: f32) -> bool {
    t - first > separation
}

impl HitReducer {
    /// Adds the hit at ray parameter `t` (ignored unless `0 < t <` [`HitReducer::second`]: a
    /// hit at or beyond the second can change nothing) whose surface faces the origin when
    /// `faces` (pass `true` for every hit to take the second hit whichever way it faces).
    #[inline]
    pub fn add(&mut self, t: f32, faces: bool, separation: f32) {
        if !(t > 0.0 && t < self.second) {
            return;
        }
        // The common cases inline (the first hit, or one beyond it), the re-sort out of line.
        if self.first == f32::INFINITY {
            self.first = t;
            self.faces = u8::from(faces) << CLUSTER;
            return;
        }
        if t < self.first {
            self.nearer_first(t, faces, separation);
        } else if !beyond(t, self.first, separation) {
            self.push(t, faces);
        } else if faces {
            self.second = t;
        }
    }

    /// [`HitReducer::add`] of a hit nearer than the first: the old first and its cluster are
    /// sorted again around the new one.
    #[inline(never)]
    fn nearer_first(&mut self, t: f32, faces: bool, separation: f32) {
        let old = (self.first, self.faces & (1 << CLUSTER) != 0);
        let old_cluster = self.cluster;
        let old_faces = self.faces;
        let old_len = self.len as usize;
        self.first = t;
        self.faces = u8::from(faces) << CLUSTER;
        self.len = 0;
        let members = old_cluster[..old_len]
            .iter()
            .enumerate()
            .map(|(i, &m)| (m, old_faces & (1 << i) != 0))
            .chain(std::iter::once(old).filter(|&(m, _)| m.is_finite()));
        for (m, m_faces) in members {
            if beyond(m, t, separation) {
                if m_faces && m < self.second {
                    self.second = m;
                }
            } else {
                self.push(m, m_faces);
            }
        }
    }

    #[inline]
    fn push(&mut self, t: f32, faces: bool) {
        let i = self.len as usize;
        if i == CLUSTER {
            self.overflowed = true;
            return;
        }
        self.cluster[i] = t;
        self.faces |= u8::from(faces) << i;
        self.len += 1;
    }

    /// Ray parameter of the first hit, `INFINITY` if none.
    pub fn first(&self) -> f32 {
        self.first
    }

    /// Whether any hit within the separation of the first faces the origin.
    pub fn first_faces(&self) -> bool {
        self.faces != 0
    }

    /// Ray parameter of the nearest facing hit more than the separation beyond the first,
    /// `INFINITY` if none. Also the bound beyond which no hit matters any more (a traversal's
    /// `tmax`).
    pub fn second(&self) -> f32 {
        self.second
    }

    /// More hits than the reducer keeps fell within the separation of the first: its answer
    /// may be wrong, reduce the ray's full hit list with [`reduce_hits`] instead.
    pub fn overflowed(&self) -> bool {
        self.overflowed
    }

    /// The answer as a [`FrontHit`].
    pub fn hit(&self) -> FrontHit {
        FrontHit {
            first: self.first,
            first_faces: self.first_faces(),
            second: self.second,
        }
    }
}

/// The definition [`HitReducer`] streams: over the hits `(t, faces)` with `0 < t < INFINITY`,
/// `first` is the nearest, `first_faces` whether any hit within `separation` of it faces the
/// origin, and `second` the nearest facing hit more than `separation` beyond the first.
/// Independent of the hits' order.
pub fn reduce_hits(hits: &[(f32, bool)], separation: f32) -> FrontHit {
    let valid = || hits.iter().filter(|&&(t, _)| t > 0.0 && t < f32::INFINITY);
    let first = valid().map(|&(t, _)| t).fold(f32::INFINITY, f32::min);
    let first_faces = valid().any(|&(t, f)| f && !beyond(t, first, separation));
    let second = valid()
        .filter(|&&(t, f)| f && beyond(t, first, separation))
        .map(|&(t, _)| t)
        .fold(f32::INFINITY, f32::min);
    FrontHit {
        first,
        first_faces,
        second,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Random hit lists, many hits close together (shared edges, vertices, thin slabs), in
    /// random orders: the streamed reduction equals the definition whenever it does not
    /// overflow, and overflows only with more than [`CLUSTER`] hits besides a first.
    #[test]
    fn hit_reducer_is_reduce_hits_in_any_order() {
        let mut rng = crate::SplitMix64(7);
        let separation = 1e-3;
        let mut overflows = 0;
        for case in 0..20_000 {
            let count = 1 + (rng.next_f64() * 7.0) as usize;
            let mut hits: Vec<(f32, bool)> = (0..count)
                .map(|_| {
                    // Hits on a grid of a third of the separation, so clusters, exact ties and
                    // chains spanning more than the separation all occur.
                    let t = 1.0 + (rng.next_f64() * 12.0).floor() as f32 * separation / 3.0;
                    let t = if rng.next_f64() < 0.1 { -t } else { t };
                    (t, rng.next_f64() < 0.5)
                })
                .collect();
            let expected = reduce_hits(&hits, separation);
            for _ in 0..4 {
                for i in (1..hits.len()).rev() {
                    let j = (rng.next_f64() * (i + 1) as f64) as usize;
                    hits.swap(i, j.min(i));
                }
                let mut r = HitReducer::default();
                for &(t, f) in &hits {
                    r.add(t, f, separation);
                }
                if r.overflowed() {
                    overflows += 1;
                    // Only with more hits than the cluster holds, within the separation of one
                    // of them (a first on the way).
                    let valid = hits.iter().filter(|&&(t, _)| t > 0.0).count();
                    assert!(valid > CLUSTER + 1, "case {case}: {hits:?}");
                } else {
                    assert_eq!(r.hit(), expected, "case {case}: {hits:?}");
                }
            }
        }
        // The fallback path is exercised, but rarely.
        assert!(overflows > 0 && overflows < 20_000, "{overflows}");
    }
}
