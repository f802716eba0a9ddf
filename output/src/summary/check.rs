//! `cssm check`'s summary ([`CheckSummary`]): the CSSM's agreement with exact ray casts, over
//! every pair and over the pairs that exchange light, and what explains the disagreements.

use std::{
    fmt,
    path::{Path, PathBuf},
};

use serde::{Deserialize, Serialize};

use super::json_line;
use cssm_bake::{self as bake, check::Agreement};

/// `cssm check`: the confusion matrix of the CSSM against exact ray casts over every pair, and
/// the agreement over the pairs that exchange light ([`bake::check::Measurement`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CheckSummary {
    /// The `.cssm` file, as given (the text's first line; not in the JSON).
    #[serde(skip)]
    pub file: PathBuf,
    /// Pairs tested (the sender point had a texel).
    pub pairs: u64,
    /// Pairs skipped: no texel stood for either point.
    pub unmapped: u64,
    /// Truly visible, reported visible.
    pub visible_visible: u64,
    /// Truly visible, reported occluded.
    pub visible_occluded: u64,
    /// Truly occluded, reported visible.
    pub occluded_visible: u64,
    /// Truly occluded, reported occluded.
    pub occluded_occluded: u64,
    /// Fraction of the pairs where the CSSM agrees with the ray cast.
    pub agreement: f64,
    /// Truly occluded pairs reported visible, as a fraction of the truly occluded.
    pub false_visible_rate: f64,
    /// Truly visible pairs reported occluded, as a fraction of the truly visible.
    pub false_occluded_rate: f64,
    /// Pairs that exchange light (each point in front of the other's surface).
    pub exchanging_pairs: u64,
    /// [`Self::agreement`] over the pairs that exchange light.
    pub exchanging_agreement: f64,
    /// [`Self::false_visible_rate`] over the pairs that exchange light.
    pub exchanging_false_visible_rate: f64,
    /// [`Self::false_occluded_rate`] over the pairs that exchange light.
    pub exchanging_false_occluded_rate: f64,
    /// Disagreements over the pairs that exchange light that the atlas explains
    /// ([`bake::check::Causes`]).
    #[serde(default)]
    pub causes_atlas: u64,
    /// ... that the near distance explains.
    #[serde(default)]
    pub causes_near: u64,
    /// ... that the sender texel's own cube map explains.
    #[serde(default)]
    pub causes_cube: u64,
    /// ... that the filters (sender filter, both ends) explain.
    #[serde(default)]
    pub causes_filter: u64,
    /// Time of the measurement.
    pub seconds: f64,
    /// The confusion matrix of the pairs that exchange light, for the text (not in the JSON:
    /// `None` when read back from it).
    #[serde(skip)]
    pub exchanging: Option<Agreement>,
}

impl CheckSummary {
    /// The summary of measurement `m` of the file `file`, which took `seconds`.
    pub fn new(file: &Path, m: &bake::check::Measurement, seconds: f64) -> Self {
        let (a, x) = (&m.all, &m.exchanging);
        Self {
            file: file.to_path_buf(),
            pairs: a.total(),
            unmapped: a.unmapped,
            visible_visible: a.visible_visible,
            visible_occluded: a.visible_occluded,
            occluded_visible: a.occluded_visible,
            occluded_occluded: a.occluded_occluded,
            agreement: a.agreement(),
            false_visible_rate: a.false_visible_rate(),
            false_occluded_rate: a.false_occluded_rate(),
            exchanging_pairs: x.total(),
            exchanging_agreement: x.agreement(),
            exchanging_false_visible_rate: x.false_visible_rate(),
            exchanging_false_occluded_rate: x.false_occluded_rate(),
            causes_atlas: m.causes.atlas,
            causes_near: m.causes.near,
            causes_cube: m.causes.cube,
            causes_filter: m.causes.filter,
            seconds,
            exchanging: Some(*x),
        }
    }

    /// The confusion matrix over every pair.
    pub fn all(&self) -> Agreement {
        Agreement {
            visible_visible: self.visible_visible,
            visible_occluded: self.visible_occluded,
            occluded_visible: self.occluded_visible,
            occluded_occluded: self.occluded_occluded,
            unmapped: self.unmapped,
        }
    }

    /// `--json`: one line.
    pub fn to_json(&self) -> String {
        json_line(self)
    }
}

impl fmt::Display for CheckSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "{}: {} random surface point pairs against exact ray casts",
            self.file.display(),
            self.pairs
        )?;
        writeln!(f, "{}", self.all())?;
        writeln!(
            f,
            "\nthe {} of them that exchange light (each in front of the other's surface):",
            self.exchanging_pairs
        )?;
        match &self.exchanging {
            Some(x) => write!(f, "{x}")?,
            None => write!(
                f,
                "agreement {:.3}% of {} pairs; occluded reported visible {:.3}%; visible reported occluded {:.3}%",
                100.0 * self.exchanging_agreement,
                self.exchanging_pairs,
                100.0 * self.exchanging_false_visible_rate,
                100.0 * self.exchanging_false_occluded_rate
            )?,
        }
        let wrong = self.causes_atlas + self.causes_near + self.causes_cube + self.causes_filter;
        if wrong > 0 {
            let share = |n: u64| 100.0 * n as f64 / self.exchanging_pairs.max(1) as f64;
            write!(
                f,
                "\ndisagreements by cause, seen from the sender (% of these pairs): atlas {:.3}% \
                 (--atlas), near distance {:.3}% (--near), cube map {:.3}% (--cube), filters \
                 {:.3}%",
                share(self.causes_atlas),
                share(self.causes_near),
                share(self.causes_cube),
                share(self.causes_filter)
            )?;
        }
        if self.unmapped > 0 {
            write!(
                f,
                "\n({} pairs had no texel for either point and were skipped)",
                self.unmapped
            )?;
        }
        Ok(())
    }
}
