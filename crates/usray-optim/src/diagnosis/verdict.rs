//! Step 5 of a diagnosis: which refitted effect, if any, the data name, and
//! what to say when none qualifies (module docs of [`crate::diagnosis`]).

use super::results::EffectResult;

/// Held-out shrinks closer than this to the verdict's are reported as
/// [`Verdict::alternatives`]: the data do not tell such effects apart
/// (e.g. attenuation in an object's material and in the background).
pub(crate) const TIE_MARGIN: f64 = 0.05;

/// The thresholds of the verdict ([`name_effect`], module docs step 5).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct VerdictRule {
    /// A refitted effect is named only if its held-out shrink beats the null
    /// refit's ([`super::Diagnosis::null_refit`]) by at least this share of the
    /// held-out calibrated loss (its *excess*, [`EffectResult::excess`]; default
    /// 0.2: above what candidates reach on data with no effect or an
    /// out-of-catalogue one, where a significant but small excess is common;
    /// docs/diagnosis.md).
    pub min_excess: f64,
    /// … and by at least this many of the excess's standard errors (default 3).
    pub min_excess_z: f64,
    /// Where a real gap remains (held-out calibrated loss above
    /// [`VerdictRule::noise_factor`] × the noise level), an effect is named
    /// only if it removes at least this share of the gap above the noise level
    /// ([`EffectResult::gap_explained`]; default 0.25: between what the best
    /// candidate absorbs of an out-of-catalogue gap, such as a wire's echo, and
    /// what a real effect in full-wave data removes, since a model-form
    /// residual stays with data the model cannot reproduce; docs/diagnosis.md);
    /// otherwise the verdict is `"unexplained"`.
    pub min_gap_explained: f64,
    /// The gap is real when the held-out calibrated loss exceeds this multiple
    /// of the Monte Carlo noise level; without a named effect the verdict is
    /// then `"unexplained"`, else `"none"` (default 1.5).
    pub noise_factor: f64,
}

impl Default for VerdictRule {
    /// Excess ≥ 0.2 and ≥ 3 standard errors; a quarter of the gap where it is
    /// real, which it is above 1.5 × the noise level.
    fn default() -> Self {
        Self {
            min_excess: 0.2,
            min_excess_z: 3.0,
            min_gap_explained: 0.25,
            noise_factor: 1.5,
        }
    }
}

/// The verdict.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Verdict {
    /// An effect name, `"none"`, `"unexplained"` or `"inconclusive"`.
    pub effect: String,
    /// The named effect's parameter (absent when no effect is named).
    pub path: Option<String>,
    /// The named effect's held-out shrink (0 for none/unexplained).
    pub shrink: f64,
    /// Other refitted effects that explain the data about as well: they pass
    /// the same tests as the named one ([`name_effect`]) and their held-out
    /// shrink is within 0.05 of its. These data do not tell them apart
    /// (e.g. attenuation in the object's material and in the background, which
    /// darken the far wall alike).
    pub alternatives: Vec<String>,
}

/// Which refitted effect the verdict names. A refit qualifies when
/// 1. it beats the null refit: its [`EffectResult::excess`] is at least
///    [`VerdictRule::min_excess`] and at least
///    [`VerdictRule::min_excess_z`] standard errors (with one held-out seed,
///    the first test alone) — an effect that only lets the base parameters
///    converge further does not;
/// 2. where the gap is real (`real_gap`: the held-out calibrated loss above
///    [`VerdictRule::noise_factor`] × the noise level), it removes at least
///    [`VerdictRule::min_gap_explained`] of the gap above the noise level — a
///    candidate that absorbs a little of an out-of-catalogue gap (a wire's echo)
///    does not.
///
/// Among the qualifying refits, those whose held-out shrink comes within
/// 0.05 of the largest tie (the data do not tell them apart), and
/// the one with the highest score is named — the effect that explains the gap
/// along its own parameter at the calibrated point, rather than with the base
/// parameters' help in its refit. Returns its index and the indices of all
/// tied refits (itself included); `None` when no refit qualifies.
///
/// ```
/// use std::collections::BTreeMap;
/// use usray_optim::{name_effect, EffectResult, VerdictRule};
/// let refit = |score: f64, shrink: f64, excess: f64, gap: f64| EffectResult {
///     effect: "e".into(), path: "p".into(), score, onset: 0.0, range: [0.0, 1.0], null: Some(0.0),
///     gradient: 0.0, loss_onset: 1.0, loss_after: Some(1.0 - shrink),
///     shrink: Some(shrink), shrink_std: Some(0.01), excess: Some(excess),
///     excess_std: Some(0.01), excess_spatial_std: None, gap_explained: Some(gap), held_out_losses: vec![],
///     params: BTreeMap::new(), params_std: BTreeMap::new(), detection_limit: None, failed: None,
/// };
/// let rule = VerdictRule::default();
/// // Shrinks 0.80 and 0.78 tie; the first has the higher score.
/// let r = [refit(0.5, 0.80, 0.7, 0.9), refit(0.1, 0.78, 0.7, 0.9), refit(0.2, 0.1, 0.0, 0.1)];
/// assert_eq!(name_effect(&r, true, &rule), Some((0, vec![0, 1])));
/// // A shrink the null refit achieves as well is no explanation…
/// assert!(name_effect(&[refit(0.3, 0.35, 0.05, 0.9)], true, &rule).is_none());
/// // …nor is a real gap only a fifth of which is removed.
/// assert!(name_effect(&[refit(0.3, 0.25, 0.25, 0.2)], true, &rule).is_none());
/// // Within the noise level the gap test does not apply.
/// assert_eq!(name_effect(&[refit(0.3, 0.25, 0.25, 0.2)], false, &rule).unwrap().0, 0);
/// ```
pub fn name_effect(
    refits: &[EffectResult],
    real_gap: bool,
    rule: &VerdictRule,
) -> Option<(usize, Vec<usize>)> {
    let qualifies = |e: &EffectResult| {
        let Some(excess) = e.excess else {
            return false;
        };
        let certain = e
            .excess_std
            .is_none_or(|se| excess >= rule.min_excess_z * se);
        let explains = !real_gap || e.gap_explained.unwrap_or(0.0) >= rule.min_gap_explained;
        excess >= rule.min_excess && certain && explains
    };
    let shrink = |i: usize| refits[i].shrink.unwrap_or(f64::NEG_INFINITY);
    let qualified: Vec<usize> = (0..refits.len())
        .filter(|&i| qualifies(&refits[i]))
        .collect();
    let top = qualified
        .iter()
        .map(|&i| shrink(i))
        .fold(f64::NEG_INFINITY, f64::max);
    let tied: Vec<usize> = qualified
        .into_iter()
        .filter(|&i| shrink(i) > top - TIE_MARGIN)
        .collect();
    let named = tied
        .iter()
        .copied()
        .max_by(|&a, &b| refits[a].score.total_cmp(&refits[b].score))?;
    Some((named, tied))
}

/// The verdict when no refit qualifies ([`name_effect`]).
///
/// A refit that still beats the null refit significantly (excess at least
/// [`VerdictRule::min_excess`] and [`VerdictRule::min_excess_z`] standard
/// errors) without explaining enough of the gap says something structured is
/// there that no candidate accounts for: `"unexplained"`. Otherwise, where the
/// simulation's noise is a small enough share of the gap (`noise_passed`,
/// [`crate::NoiseCheck`]) to have seen an effect above its limit of detection,
/// `"none"`; where it is not, `"inconclusive"`, never `"none"`: the noise may
/// hide an effect.
///
/// ```
/// use usray_optim::{unnamed_verdict, VerdictRule};
/// let rule = VerdictRule::default();
/// assert_eq!(unnamed_verdict(&[], &rule, true), "none");
/// assert_eq!(unnamed_verdict(&[], &rule, false), "inconclusive");
/// ```
pub fn unnamed_verdict(
    refits: &[EffectResult],
    rule: &VerdictRule,
    noise_passed: bool,
) -> &'static str {
    let significant = refits.iter().any(|e| {
        e.excess.is_some_and(|x| {
            x >= rule.min_excess && e.excess_std.is_none_or(|se| x >= rule.min_excess_z * se)
        })
    });
    match (significant, noise_passed) {
        (true, _) => "unexplained",
        (false, true) => "none",
        (false, false) => "inconclusive",
    }
}

/// Whether a verdict names an effect (not `"none"`, `"unexplained"` or
/// `"inconclusive"`).
///
/// ```
/// assert!(usray_optim::names_an_effect("attenuation"));
/// assert!(!usray_optim::names_an_effect("inconclusive"));
/// ```
pub fn names_an_effect(verdict: &str) -> bool {
    !matches!(verdict, "none" | "unexplained" | "inconclusive")
}
