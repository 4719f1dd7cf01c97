//! The report of a diagnosis (CONTRACT §5): `report.md`, the story of every
//! round with its tables, and `diagnosis.json`, the first round's
//! [`Diagnosis`] with the kinds of residual and one summary per round.
//!
//! The report names the figures `usray diagnose` draws beside it
//! (`measured.png`, `calibrated.png`, `after.png`, `residual_calibrated.png`,
//! `residual_after.png`) and the command's flags for each setting
//! (`--smoothing` for [`super::DiagnoseOptions::smoothing_wavelengths`], …).

use super::refits::DETECTION_LIMIT_SPREADS;
use super::residual::{residual_scale, GreyStats, ResidualReport};
use super::results::{Confirmation, Diagnosis, EffectResult, SpectralAttenuation, SpectralCentre};
use super::verdict::{names_an_effect, TIE_MARGIN};
use crate::mirror::impedance_mirror;
use crate::objective::grid_shape;
use crate::OptimError;
use std::fmt::{self, Write as _};
use std::path::Path;
use usray_signal::SpectralShift;
use usray_transport::Scene;

/// A diagnosis's rounds ([`super::diagnose_compound`]) and what the report
/// says about where they came from.
///
/// ```no_run
/// use std::path::Path;
/// use usray_optim::{diagnose_compound, load_reference, DiagnoseOptions, Report};
/// let scene = usray_transport::Scene::load("scene.toml").unwrap();
/// let measured = load_reference(Path::new("measured/bmode.npy"), &scene).unwrap();
/// let t = std::time::Instant::now();
/// let rounds = diagnose_compound(&scene, &measured, &DiagnoseOptions::default(), 2, |_| {}).unwrap();
/// let report = Report {
///     rounds: &rounds,
///     scene: &scene,
///     scene_path: Path::new("scene.toml"),
///     measured_path: Path::new("measured/bmode.npy"),
///     measured: &measured,
///     wall_s: t.elapsed().as_secs_f64(),
///     dimensions_note: None,
/// };
/// report.write(Path::new("diagnosis")).unwrap(); // report.md, diagnosis.json
/// ```
#[derive(Clone, Copy, Debug)]
pub struct Report<'a> {
    /// Every round, the first one the diagnosis proper (at least one).
    pub rounds: &'a [Diagnosis],
    /// The scene diagnosed (the base model, as loaded).
    pub scene: &'a Scene,
    /// Its file, as the report names it.
    pub scene_path: &'a Path,
    /// The measured data's file, as the report names it.
    pub measured_path: &'a Path,
    /// The measured B-mode the diagnosis compared with (`[nz, nx]` on the
    /// scene's grid): the residual figures' scales are quoted from it.
    pub measured: &'a [f64],
    /// Wall time of the whole diagnosis, seconds.
    pub wall_s: f64,
    /// Why the scene is traced in 2-D when its file leaves the dimensions
    /// unset and the measured data declare a 2-D simulation (the CLI's
    /// sentence), else `None`.
    pub dimensions_note: Option<&'a str>,
}

impl Report<'_> {
    /// `report.md`: the verdict and what it rests on, the calibrated model,
    /// where the residual lies, every candidate, the compound rounds and the
    /// time.
    ///
    /// # Errors
    /// No rounds, or images that do not match the scene's grid.
    pub fn markdown(&self) -> Result<String, OptimError> {
        let d = self.first()?;
        let (nz, nx) = grid_shape(self.scene)?;
        let scale_before = residual_scale(&d.calibrated_image, self.measured, nz, nx)?;
        let scale_after = residual_scale(&d.after_image, self.measured, nz, nx)?;
        story(self, scale_before, scale_after)
            .map_err(|_| OptimError::Diagnosis("report.md: formatting failed".into()))
    }

    /// `diagnosis.json` (CONTRACT §5): the first round at the top level, with
    /// `residual_kinds` and `wall_seconds`; every round's verdict, named
    /// effect and ranked candidates in `rounds`.
    ///
    /// # Errors
    /// No rounds.
    pub fn json(&self) -> Result<serde_json::Value, OptimError> {
        let d = self.first()?;
        let unserialisable =
            |e: serde_json::Error| OptimError::Diagnosis(format!("diagnosis.json: {e}"));
        let mut json = serde_json::to_value(d).map_err(unserialisable)?;
        json["residual_kinds"] = serde_json::to_value(&d.residual).map_err(unserialisable)?;
        json["wall_seconds"] = self.wall_s.into();
        json["dimensions"] = u8::from(self.scene.acquisition.dimensions.unwrap_or_default()).into();
        json["dimensions_from_data"] = self.dimensions_note.into();
        json["reference_amplitude"] = self.scene.imaging.reference_amplitude.into();
        json["rounds"] = serde_json::Value::Array(
            self.rounds
                .iter()
                .map(|r| {
                    let named = named_effect(r);
                    serde_json::json!({
                        "verdict": r.verdict,
                        "gap_explained": named.and_then(|e| e.gap_explained),
                        "excess": named.and_then(|e| e.excess),
                        "excess_std": named.and_then(|e| e.excess_std),
                        "excess_spatial_std": named.and_then(|e| e.excess_spatial_std),
                        "confirmation": named.and_then(|e| e.confirmation.clone()),
                        "more_rays": named.and_then(|e| e.more_rays.clone()),
                        "found": named.and_then(|e| e.params.get(&e.path)),
                        "noise_check": r.noise_check,
                        "loss_held_out": r.calibrated.loss_held_out,
                        "seconds": r.timings.total_s,
                        "next_round_stopped": r.next_round_stopped,
                        "spectral_shift": r.spectral_shift,
                        "spectral_attenuation": r.spectral_attenuation,
                        "spectral_centre": r.spectral_centre,
                        "effects": r.effects,
                    })
                })
                .collect(),
        );
        Ok(json)
    }

    /// Writes `report.md` and `diagnosis.json` (pretty-printed) into `dir`,
    /// each atomically. The figures the report shows are not drawn here
    /// (`usray diagnose` draws them).
    ///
    /// # Errors
    /// As [`Report::markdown`] and [`Report::json`], or a file that cannot be
    /// written (named).
    pub fn write(&self, dir: &Path) -> Result<(), OptimError> {
        let json = serde_json::to_string_pretty(&self.json()?)
            .map_err(|e| OptimError::Diagnosis(format!("diagnosis.json: {e}")))?;
        for (name, text) in [("report.md", self.markdown()?), ("diagnosis.json", json)] {
            let path = dir.join(name);
            usray_signal::write_atomic(&path, |w| w.write_all(text.as_bytes())).map_err(|e| {
                OptimError::Diagnosis(format!("cannot write {}: {e}", path.display()))
            })?;
        }
        Ok(())
    }

    /// The first round, the diagnosis proper.
    fn first(&self) -> Result<&Diagnosis, OptimError> {
        self.rounds
            .first()
            .ok_or_else(|| OptimError::Diagnosis("a report needs at least one round".into()))
    }
}

/// How the report's losses compared the images: the smoothing in mm and the
/// noise floor in grey levels and dB below the top of the dynamic range.
fn comparison_sentence(d: &Diagnosis, scene: &Scene) -> String {
    let c = &d.comparison;
    let pixel_mm = 1e3 * scene.imaging.pixel_m;
    let smoothing = if c.sigma_z_px > 0.0 {
        format!(
            "after smoothing both by a Gaussian of σ = {:.3} mm (`--smoothing`), so that speckle and noise average out",
            c.sigma_z_px * pixel_mm
        )
    } else {
        "pixel by pixel".to_string()
    };
    let floor = if c.floor > 0.0 {
        format!(
            ", and floored at grey {:.3} ({:.1} dB): the measurement's noise level where the calibrated model's image is empty (`usray_optim::noise_floor`, `--floor`), below which a difference is no evidence",
            c.floor,
            -(1.0 - c.floor) * scene.imaging.dynamic_range_db
        )
    } else {
        ", with no noise floor (`--floor` adds one)".to_string()
    };
    format!("Every loss after the calibration compares the images {smoothing}{floor}.")
}

/// The refitted effect a diagnosis's verdict names, if any.
fn named_effect(d: &Diagnosis) -> Option<&EffectResult> {
    let path = d.verdict.path.as_ref()?;
    d.effects.iter().find(|e| &e.path == path)
}

/// The story of a diagnosis: `report.md`'s text ([`Report::markdown`]).
fn story(report: &Report, scale_before: f64, scale_after: f64) -> Result<String, fmt::Error> {
    let (rounds, base, wall) = (report.rounds, report.scene, report.wall_s);
    let (scene, measured) = (report.scene_path, report.measured_path);
    let d = &rounds[0];
    let mut r = String::new();
    writeln!(
        r,
        "# usray diagnose: `{}` against `{}`\n",
        scene.display(),
        measured.display()
    )?;
    writeln!(r, "## Verdict: **{}**\n", d.verdict.effect)?;
    let nc = &d.noise_check;
    match d.verdict.effect.as_str() {
        "none" => writeln!(r, "No candidate effect shrinks the held-out loss significantly more than refitting the base parameters alone does (by {:.0} standard errors over the held-out seeds and {:.0} over the image's blocks), and the simulation's Monte Carlo noise was small enough to see one: {:.0}% of the calibrated gap at {} rays (at most {:.0}%). The limits of detection below say how weak an effect could still go unseen.\n", d.rule.min_excess_z, d.rule.min_spatial_z, 100.0 * nc.share, nc.rays, 100.0 * nc.target)?,
        "unexplained" => writeln!(r, "A gap remains (held-out loss {:.4e} against a Monte Carlo noise level of {:.4e}, both averaged over {} seeds) that a candidate shrinks by at least {:.0}% of the loss more than refitting the base parameters alone, but not across the image: its gain lies in a few places and is paid for in others. Something the catalogue does not hold is there; see where the residual lies (section 2).\n", d.calibrated.loss_held_out, d.noise_loss, d.held_out_seeds, 100.0 * d.rule.large_excess)?,
        "inconclusive" => {
            if !nc.passed {
                writeln!(r, "The simulation's own Monte Carlo noise is {:.0}% of the calibrated gap at {} rays per element (a decision needs at most {:.0}%), so a candidate could win or lose by fitting noise, and no effect was found that clears it.", 100.0 * nc.share, nc.rays, 100.0 * nc.target)?;
                match (nc.rays_needed, nc.seconds_needed) {
                    (Some(rays), Some(s)) => writeln!(r, "A decision needs about **{rays} rays**, about {s:.0} s for the whole diagnosis on this machine: rerun with `--budget {:.0}` (or `--rays {rays}`).\n", s.ceil())?,
                    _ => writeln!(r, "The calibrated model's held-out loss is no larger than its own noise: no gap is visible at this noise level, and how many rays would show one cannot be told from it. Rerun with several times the rays.\n")?,
                }
            }
            for e in &d.effects {
                if let Some(Confirmation::OverBudget { seeds, estimate_s, left_s }) = e.confirmation {
                    writeln!(r, "`{}` (`{}`) passes every test but one: its gain over the null refit, {}, is {} standard errors over the {} held-out seeds, more than {:.0} but fewer than {:.0}. Such a borderline gain is measured again on {seeds} fresh seeds before it is named or ruled out, which would take about {estimate_s:.0} s, and {:.0} s of the budget was left. Rerun with a budget about {:.0} s larger.\n", e.effect, e.path, excess_text(e), first_look_z(e), e.held_out_losses.len(), d.rule.borderline_z, d.rule.min_excess_z, left_s.max(0.0), (10.0 * ((estimate_s - left_s) / 10.0).ceil()).max(10.0))?;
                }
            }
        }
        // Named by the echoes' spectra: their paragraph below says how.
        _ if d.spectral_attenuation.as_ref().is_some_and(|s| s.named) => {}
        e => {
            writeln!(r, "Switching on `{e}` and refitting shrinks the held-out loss by **{:.0}%** (from {:.4e}); refitting the base parameters alone for as long (the null refit) changes it by {}.", 100.0 * d.verdict.shrink, d.calibrated.loss_held_out, signed_percent(-d.null_refit.shrink))?;
            if let Some(g) = named_effect(d).and_then(|x| x.gap_explained) {
                writeln!(r, "It removes {:.0}% of the gap above the Monte Carlo noise level ({:.4e}).", 100.0 * g, d.noise_loss)?;
            }
            writeln!(r)?
        }
    }
    if !names_an_effect(&d.verdict.effect) {
        let limits: Vec<String> = d
            .effects
            .iter()
            .filter_map(|e| {
                let (limit, null) = (e.detection_limit?, e.null?);
                let found = e.params.get(&e.path)? - null;
                let z = e.null_z()?;
                Some(format!(
                    "{} (`{}`) within {}{} of {} (found {}: {z:+.1} spreads)",
                    e.effect,
                    e.path,
                    if e.range[0] < null { "±" } else { "+" },
                    short(limit),
                    short(null),
                    signed(found)
                ))
            })
            .collect();
        if !limits.is_empty() {
            writeln!(r, "**What these data cannot rule out.** Within its limit of detection — {:.0} Monte Carlo spreads of its refitted value from its null — an effect cannot be told from its absence by its parameter, so one weaker than this could be present: {}. These limits are lower bounds: the spreads count Monte Carlo noise only, and a value found beyond its limit is not thereby an effect (the held-out loss decides that).\n", DETECTION_LIMIT_SPREADS, limits.join("; "))?;
        }
        // Refits whose gain was significant but whose value ended within its
        // tolerance of the model's: not named, and the user should know why.
        let small: Vec<String> = d
            .effects
            .iter()
            .filter(|e| e.within_tolerance() && d.rule.significant(e))
            .filter_map(|e| {
                let (excess, se_image) = (e.excess?, e.excess_spatial_std?);
                let se = plus_minus(e.excess_std);
                Some(format!(
                    "{} (`{}`) gained {excess:+.3}{se} (± {se_image:.3} over the image) over the null refit but moved {} from the modelled value, within its tolerance ±{}",
                    e.effect,
                    e.path,
                    signed(e.params[&e.path] - e.null?),
                    short(e.tolerance?)
                ))
            })
            .collect();
        if !small.is_empty() {
            writeln!(r, "**Significant, but too small to matter:** {}. A departure within its tolerance leaves the image as it was or changes only what a base parameter changes too (the rule is under “Candidate effects”), so its gain is the base model being adjusted through this parameter, not this effect.\n", small.join("; "))?;
        }
    }
    for e in &d.effects {
        if let Some(Confirmation::Measured {
            seeds,
            excess,
            excess_std,
            ..
        }) = e.confirmation
        {
            let z = excess_std.map_or(String::new(), |se| {
                format!(", {:.1} standard errors", excess / se)
            });
            let outcome = if d.rule.significant(e) {
                "significant there"
            } else {
                "not significant there"
            };
            writeln!(r, "**Measured again on fresh seeds:** `{}`'s gain over the null refit, {} ({} standard errors over the {} held-out seeds, between {:.0} and {:.0}: borderline), was rendered again with the control on {seeds} seeds none of the above used: {excess:+.3}{}{z}, {outcome}. The seeds' test is decided on those alone, so the second look does not raise the chance of naming an effect by chance.\n", e.effect, excess_text(e), first_look_z(e), e.held_out_losses.len(), d.rule.borderline_z, d.rule.min_excess_z, plus_minus(excess_std))?;
        }
    }
    for e in &d.effects {
        if let Some(m) = &e.more_rays {
            let outcome = if d.rule.holds_without_noise(Some(m)) {
                "it holds without the noise"
            } else {
                "**it does not hold without the noise, so it is not named**: the candidate darkened the simulation's own Monte Carlo clutter rather than explained the data"
            };
            writeln!(r, "**At four times the rays:** `{}`'s gain over the null refit, {} at the first look, is {:+.3}{} with both rendered again at {} rays on the held-out seeds. The simulation's noise falls as rays^−{:.2} (the noise levels at both counts), and so does any gain that is only the noise's; extrapolated to no noise the gain is {:+.3}{}: {outcome}.\n", e.effect, excess_text(e), m.excess, plus_minus(m.excess_std), m.rays, m.noise_exponent, m.noise_free_excess, plus_minus(m.noise_free_std))?;
        }
    }
    if let Some(named) = named_effect(d).filter(|e| e.at_range_bound()) {
        writeln!(r, "**At the bound of its range:** the refit left `{}` at {:.4e}, the edge of the range [{:.4e}, {:.4e}] it may take; the data may want a stronger effect than the range allows, so this value is a limit, not an estimate.\n", named.path, named.params[&named.path], named.range[0], named.range[1])?;
    }
    if let Some(sc) = &d.spectral_centre {
        spectral_centre_paragraph(&mut r, "The echoes' centre frequency", sc)?;
        if let Some(width) = named_effect(d).filter(|e| e.effect == "element_width") {
            width_beside_centre_paragraph(&mut r, width, sc)?;
        }
    }
    if let Some(shift) = &d.spectral_shift {
        spectral_paragraph(&mut r, "The echoes' spectra", d, shift)?;
    }
    if let Some(sa) = &d.spectral_attenuation {
        spectral_attenuation_paragraph(&mut r, "The echoes' spectra along their path", d, sa)?;
    }
    if !d.verdict.alternatives.is_empty() {
        let alt: Vec<String> = d
            .verdict
            .alternatives
            .iter()
            .map(|a| format!("`{a}`"))
            .collect();
        writeln!(r, "**Not told apart:** {} explain(s) these data about as well (held-out shrink within {:.2}); more data (other angles, depths, channel data) would be needed to choose.\n", alt.join(", "), TIE_MARGIN)?;
    }
    writeln!(r, "## 1. Calibrated base model\n")?;
    writeln!(
        r,
        "| parameter | your scene | calibrated | change | ± (Monte Carlo spread) |\n|---|---|---|---|---|"
    )?;
    let mut far = Vec::new();
    for (p, v) in &d.calibrated.params {
        let std = d.calibrated.params_std.get(p).copied().flatten();
        let given = scene_value(base, p);
        let change = given.and_then(|g| relative_change(g, *v));
        if let (Some(g), Some(c)) = (given, change.filter(|c| c.abs() > FAR_FROM_SCENE)) {
            far.push(format!("`{p}` {g:.3} → {v:.3} ({:+.0}%)", 100.0 * c));
        }
        writeln!(
            r,
            "| `{p}` | {} | {v:.6e} | {} | {} |",
            or_dash(given, |g| format!("{g:.6e}")),
            or_dash(change, |c| format!("{:+.0}%", 100.0 * c)),
            std_text(std)
        )?;
    }
    if !far.is_empty() {
        writeln!(r, "\n**Far from your scene's value:** {}. A base parameter the calibration moves this far may be standing in for something the model lacks, an effect among the candidates included: every candidate is scored and refitted against the calibrated model, so an effect the calibration has absorbed shows no gain. If you know a value, hold it: give `--params` the other free parameters only (docs/diagnosis.md, \"Known limits\", has a measured case).", far.join("; "))?;
    }
    for (p, v) in &d.calibrated.params {
        let mirror = p.parse().ok().and_then(|k| impedance_mirror(base, &k, *v));
        if let Some(m) = mirror {
            writeln!(r, "\n**`{p}` = {v:.3} MRayl or {m:.3}?** A B-mode barely tells an impedance `Z` from its mirror `Z₁²/Z` = {m:.3} MRayl (`Z₁` = {:.3} MRayl, the background's): the wall reflects with the opposite sign and passes with the same `1 − R²`, which the envelope does not show. Which side of `Z₁` the fit lands on depends on its start; knowing whether the target is denser than its surroundings decides it.", base.medium.impedance_mrayl)?;
        }
    }
    writeln!(r, "\n±: the standard deviation the fitted value would have under the simulation's Monte Carlo noise (a linearised fit repeated on {} independent noise realisations, `usray_optim::parameter_spread`). It counts noise only: where parameters trade against each other, or the loss is biased, the error can be many times larger (docs/diagnosis.md, \"How well each parameter is determined\").", d.spread_pairs)?;
    writeln!(
        r,
        "\nLoss {:.4e} on the fit's seed, {:.4e} held out (mean over {} other seeds); Monte Carlo noise level {:.4e}, so the simulation's own noise is {:.0}% of the held-out loss at {} rays.{}\n",
        d.calibrated.loss,
        d.calibrated.loss_held_out,
        d.held_out_seeds,
        d.noise_loss,
        100.0 * nc.share,
        nc.rays,
        if d.paired {
            " Every loss is the paired loss (`--paired`: two renders with independent seeds, unbiased in the simulation's variance in its ℓ2 term)."
        } else {
            ""
        }
    )?;
    writeln!(r, "{}\n", comparison_sentence(d, base))?;
    if let Some(note) = report.dimensions_note {
        writeln!(r, "Every model was {note}.\n")?;
    } else if base.acquisition.is_planar() {
        writeln!(r, "Every model was traced in 2-D (`acquisition.dimensions = 2`): everything stays in the `xz` plane, as in data simulated in 2-D.\n")?;
    }
    if let Some(m) = base.imaging.reference_amplitude {
        writeln!(r, "Levels are absolute: every image, measured and simulated, is in dB against one envelope, `imaging.reference_amplitude` = {m:.4e}, not each against its own maximum (`--levels absolute` or `auto` sets it to the measured image's maximum for data that declare `amplitude_unit` = \"{}\", the unit of the model's 2-D renders): an echo the model renders too strong shows too bright.\n", crate::SOURCE_PRESSURE_UNIT)?;
    }
    if d.max_bounces > base.acquisition.max_bounces {
        writeln!(r, "Every model was rendered at **{} bounces**, the scene's {} and {} more: a `wall_thickness` candidate hollows a solid cylinder, and a path then meets more surfaces before the far wall (at the scene's limit the hollowed cylinder would lose its far wall, and a true wall would look worse than none).\n", d.max_bounces, base.acquisition.max_bounces, d.max_bounces - base.acquisition.max_bounces)?;
    }
    if d.held_out_frames {
        writeln!(r, "Every held-out loss (the calibrated model's, each refit's, the null refit's) is measured against measured frames held out from the fit (`--held-out-frames` or `--held-out-measured`), so a refit that fits the fitted frames' own noise gains nothing there.\n")?;
    }
    writeln!(r, "| measured | calibrated | after the verdict's refit |\n|---|---|---|\n| ![measured](measured.png) | ![calibrated](calibrated.png) | ![after](after.png) |\n")?;
    writeln!(r, "## 2. Where the residual lies\n")?;
    writeln!(r, "Signed residual (red: simulation brighter, blue: darker; saturates at ±{scale_before:.3} grey levels, ±{:.1} dB, before and ±{scale_after:.3}, ±{:.1} dB, after; the colour bars read dB):\n\n| calibrated | after |\n|---|---|\n| ![residual](residual_calibrated.png) | ![residual after](residual_after.png) |\n", scale_before * base.imaging.dynamic_range_db, scale_after * base.imaging.dynamic_range_db)?;
    writeln!(
        r,
        "| partition | region | share of the loss |\n|---|---|---|"
    )?;
    for s in &d.where_ {
        writeln!(r, "| {} | {} | {:.3} |", s.partition, s.region, s.share)?;
    }
    residual_kinds(&mut r, &d.residual)?;
    writeln!(r, "\n## 3–4. Candidate effects\n")?;
    writeln!(r, "Score: the fraction of the calibrated loss the effect removes along its own parameter alone, the base parameters held, at the best of its onset and a Newton step from there checked by a render (on the fit's seed; `usray_optim::score_candidate`). Shrink: `1 − loss_after/loss_calibrated`, both on held-out data (the mean over {} seeds), for the refitted candidates; ± its standard error from the per-seed differences. Excess: how much more the refit shrinks the held-out loss than the null refit (the base parameters alone, refitted as long: shrink {:.3}), with its standard error over the held-out seeds and, in brackets, over blocks of the image three wavelengths wide (large when the gain lies in a few places and is paid for elsewhere); gap explained: the share of the gap above the noise level the refit removes; limit of detection: the smallest departure of the effect parameter from its null that these data resolve, {:.0} Monte Carlo spreads of the refitted value (a lower bound). An effect is named when its excess is at least {:.0} standard errors over the seeds and {:.0} over the image's blocks (and, where the simulation's noise failed its check, at least {:.2}), with its parameter inside its range rather than at a bound and, for the medium's sound speed and a modelled wall's thickness, further from the modelled value than its tolerance (Rayleigh's quarter-wavelength rule: a two-way path error of a quarter wavelength, at the image's deepest row for the speed, inside the wall for its thickness); the share of the gap it explains is reported, not required (against data the model cannot reproduce exactly, part of the gap stays whatever effect is added).\n", d.held_out_seeds, d.null_refit.shrink, DETECTION_LIMIT_SPREADS, d.rule.min_excess_z, d.rule.min_spatial_z, d.rule.large_excess)?;
    writeln!(
        r,
        "| effect | parameter | onset | score | ∂L/∂θ at onset | loss after | shrink | excess | gap explained | limit of detection | found |\n|---|---|---|---|---|---|---|---|---|---|---|"
    )?;
    for e in &d.effects {
        let mut found: Vec<String> = e
            .params
            .iter()
            .map(|(p, v)| match e.params_std.get(p).copied() {
                Some(std) => format!("`{p}` = {v:.4e} ± {}", std_text(std)),
                None => format!("`{p}` = {v:.4e}"),
            })
            .collect();
        if e.at_range_bound() {
            found.push(format!(
                "(**`{}` at the bound of its range [{:.3e}, {:.3e}]**)",
                e.path, e.range[0], e.range[1]
            ));
        }
        if let (true, Some(tol)) = (e.within_tolerance(), e.tolerance) {
            found.push(format!(
                "(**within ±{} of the modelled value: too small to matter to the image**)",
                short(tol)
            ));
        }
        writeln!(
            r,
            "| {} | `{}` | {:.4e} | {:.3e} | {:.3e} | {} | {} | {} | {} | {} | {} |",
            e.effect,
            e.path,
            e.onset,
            e.score,
            e.gradient,
            e.loss_after.map_or("—".into(), |v| format!("{v:.4e}")),
            match (e.shrink, e.shrink_std) {
                (Some(v), Some(se)) => format!("{v:.3} ± {se:.3}"),
                (Some(v), None) => format!("{v:.3}"),
                _ => "—".into(),
            },
            excess_text(e)
                + &e.excess_spatial_std
                    .map_or(String::new(), |se| format!(" (± {se:.3} over the image)"))
                + &match e.confirmation {
                    Some(Confirmation::Measured {
                        seeds,
                        excess,
                        excess_std,
                        ..
                    }) => format!(
                        "; on {seeds} fresh seeds {excess:+.3}{}",
                        plus_minus(excess_std)
                    ),
                    Some(Confirmation::OverBudget { seeds, .. }) => {
                        format!("; borderline, not measured on {seeds} fresh seeds (budget)")
                    }
                    None => String::new(),
                }
                + &e.more_rays.as_ref().map_or(String::new(), |m| {
                    format!(
                        "; at {} rays {:+.3}{}, without noise {:+.3}{}",
                        m.rays,
                        m.excess,
                        plus_minus(m.excess_std),
                        m.noise_free_excess,
                        plus_minus(m.noise_free_std)
                    )
                }),
            or_dash(e.gap_explained, |g| format!("{g:.2}")),
            match (e.detection_limit, e.null) {
                (Some(l), Some(null)) if e.range[0] < null => format!("±{}", short(l)),
                (Some(l), _) => format!("+{}", short(l)),
                _ => "—".into(),
            },
            found.join(", ")
        )?;
    }
    let failed: Vec<String> = d
        .effects
        .iter()
        .filter_map(|e| {
            Some(format!(
                "{} (`{}`): {}",
                e.effect,
                e.path,
                e.failed.as_ref()?
            ))
        })
        .collect();
    if !failed.is_empty() {
        writeln!(
            r,
            "\n**Not completed** (the diagnosis went on without them): {}.",
            failed.join("; ")
        )?;
    }
    for e in &d.effects {
        let (Some(cost), Some(v)) = (e.absence_cost, e.params.get(&e.path)) else {
            continue;
        };
        let cost_std = e.absence_cost_std.unwrap_or(f64::NAN);
        let reading = if e.at_range_bound() {
            "not told from its absence: pressed against its null, it cannot be named"
        } else if e.indistinct_from_null() {
            "not told from its absence: its gain over the null refit is not shown to be its own (the base parameters refitted beside it may carry it), so it cannot be named"
        } else {
            "the effect is there, however small its value"
        };
        writeln!(
            r,
            "\n`{}` refitted to {} (`{}`), within its limit of detection of its null; switched back to its null, every other refitted value kept, the held-out loss rises by {cost:+.3} ± {cost_std:.3} of the calibrated loss: {reading}.",
            e.effect,
            short(*v),
            e.path
        )?;
    }
    if rounds.len() > 1 || names_an_effect(&d.verdict.effect) {
        writeln!(r, "\n## Compound gap\n\nEach named effect is switched on at its refitted value, its parameter joins the calibration, and the diagnosis runs again ({} round(s) of at most the `--rounds` asked).\n", rounds.len())?;
        writeln!(r, "| round | verdict | found | excess over the null refit | gap explained | what stays (held-out loss) | noise share at rays |\n|---|---|---|---|---|---|---|")?;
        for (i, round) in rounds.iter().enumerate() {
            let named = named_effect(round);
            writeln!(
                r,
                "| {} | {} | {} | {} | {} | {:.4e} | {:.0}% at {} |",
                i + 1,
                round.verdict.effect,
                named
                    .and_then(|e| Some(format!(
                        "`{}` = {}",
                        e.path,
                        short(*e.params.get(&e.path)?)
                    )))
                    .unwrap_or_else(|| "—".into()),
                named
                    .and_then(|e| Some(match e.excess_std {
                        Some(se) => format!("{:+.3} ± {se:.3}", e.excess?),
                        None => format!("{:+.3}", e.excess?),
                    }))
                    .unwrap_or_else(|| "—".into()),
                or_dash(named.and_then(|e| e.gap_explained), |g| format!("{g:.2}")),
                named
                    .and_then(|e| e.loss_after)
                    .unwrap_or(round.calibrated.loss_held_out),
                100.0 * round.noise_check.share,
                round.noise_check.rays,
            )?;
        }
        if let Some(why) = rounds.last().and_then(|l| l.next_round_stopped.as_ref()) {
            // `why` opens with "round N stopped": a sentence of its own here.
            let (first, rest) = why.split_at(1);
            writeln!(r, "\n{}{rest}.", first.to_uppercase())?;
        }
        for (i, round) in rounds.iter().enumerate().skip(1) {
            if let Some(sc) = &round.spectral_centre {
                writeln!(r)?;
                let heading = format!("Round {}, the echoes' centre frequency", i + 1);
                spectral_centre_paragraph(&mut r, &heading, sc)?;
            }
            if let Some(shift) = &round.spectral_shift {
                writeln!(r)?;
                let heading = format!("Round {}, the echoes' spectra", i + 1);
                spectral_paragraph(&mut r, &heading, round, shift)?;
            }
            if let Some(sa) = &round.spectral_attenuation {
                writeln!(r)?;
                let heading = format!("Round {}, the echoes' spectra along their path", i + 1);
                spectral_attenuation_paragraph(&mut r, &heading, round, sa)?;
            }
            for e in &round.effects {
                let Some(a) = e.additivity.filter(|a| *a < round.rule.min_additivity) else {
                    continue;
                };
                // An additivity exists only for a candidate the first round scored.
                let Some(first) = d.effects.iter().find(|x| x.path == e.path) else {
                    continue;
                };
                writeln!(r, "\nRound {}: `{}` gains {:+.3} over the null refit here but scored {:.4} in the first round, {:.2} of what an effect adding to the first round's would have scored (at least {:.2} to be named): its gain appears only beside the earlier effect's refit, undoing what that refit did to the base parameters, so it is not named as a second effect.", i + 1, e.effect, e.excess.unwrap_or(0.0), first.score, a, round.rule.min_additivity)?;
            }
        }
    }
    let t = &d.timings;
    writeln!(r, "\n## Time\n\n{wall:.1} s in all; the first round: calibration {:.1} s, held-out evaluation {:.1} s, scoring every candidate {:.1} s, refits of the candidates {:.1} s, the null refit {:.1} s, parameter spreads {:.1} s.", t.calibration_s, t.held_out_s, t.scoring_s, t.refits_s, t.null_refit_s, t.spread_s)?;
    if nc.history.len() > 1 {
        let steps: Vec<String> = nc
            .history
            .iter()
            .map(|(rays, share)| format!("{rays} rays: {:.0}%", 100.0 * share))
            .collect();
        writeln!(
            r,
            "\nRays raised within the budget, with the simulation's noise share of the gap: {}.",
            steps.join(" → ")
        )?;
    }
    Ok(r)
}

/// What the spectral check of a centre-frequency refit found
/// ([`Diagnosis::spectral_shift`]).
fn spectral_paragraph(
    r: &mut String,
    heading: &str,
    d: &Diagnosis,
    shift: &SpectralShift,
) -> fmt::Result {
    let Some(cf) = d.effects.iter().find(|e| e.spectral_z.is_some()) else {
        return Ok(());
    };
    let reading = if d.rule.spectrum_contradicts(cf) {
        "so the centre frequency, which would shift every echo alike, is not named: it stands in for the attenuation"
    } else {
        "which does not contradict a centre frequency that shifts every echo alike"
    };
    writeln!(
        r,
        "**{heading}:** {}, {reading} (the rule: {:.0} standard errors, `usray_signal::spectral_shift`).\n",
        shift_text(shift, "the null refit's model's"),
        d.rule.min_spectral_z
    )
}

/// Where `element_width` is named beside a centre frequency the echoes'
/// spectra show (`sc`): whether the width's change could be the centre
/// frequency's. An element's directivity goes as `w·f` (Szabo, *Diagnostic
/// Ultrasound Imaging*, 2nd ed., eq. 6.16), so a wider element hears as a
/// higher frequency does; a width that moved against the spectra's centre
/// (narrower for a higher centre, wider for a lower) is not that frequency's
/// directivity, and the report says so rather than offer the trade.
fn width_beside_centre_paragraph(
    r: &mut String,
    width: &EffectResult,
    sc: &SpectralCentre,
) -> fmt::Result {
    let f_scene = sc.centre_hz - sc.offset_hz;
    let w_found = width.params.get(&width.path).copied().unwrap_or(f64::NAN);
    let w_scene = width.null.unwrap_or(width.onset);
    let same_way = (w_found - w_scene).signum() == sc.offset_hz.signum();
    if same_way {
        writeln!(r, "**An element width, or a centre frequency?** Both change how wide the element hears (its directivity goes as `w·f`, Szabo eq. 6.16), and the image barely tells one from the other; the echoes' spectra, which an element's width barely moves, show a centre of {:.3} MHz against your scene's {:.3}. If your probe's centre frequency is not known, measure it (or set it to that centre) and diagnose again.\n", sc.centre_hz / 1e6, f_scene / 1e6)
    } else {
        let (moved, hears) = if w_found < w_scene {
            ("narrower", "wider")
        } else {
            ("wider", "narrower")
        };
        writeln!(r, "**An element width beside another centre frequency.** The echoes' spectra, which an element's width barely moves, show a centre of {:.3} MHz against your scene's {:.3}, but the image prefers a {moved} element ({:.3} mm for {:.3}), which hears {hears} where that centre would make it hear the other way (directivity goes as `w·f`, Szabo eq. 6.16): the width's gain is not that centre frequency's, and may stand in for something else your model lacks. If your probe's centre frequency is not known, measure it (or set it to that centre) and diagnose again; the width's verdict may then change.\n", sc.centre_hz / 1e6, f_scene / 1e6, w_found * 1e3, w_scene * 1e3)
    }
}

/// The centre frequency the echoes' spectra showed and the range it gave the
/// centre-frequency candidate ([`Diagnosis::spectral_centre`]).
fn spectral_centre_paragraph(r: &mut String, heading: &str, sc: &SpectralCentre) -> fmt::Result {
    writeln!(
        r,
        "**{heading}:** the measured echoes' spectra lie alike along their path, centred at {:.3} ± {:.3} MHz against your scene's {:.3} MHz as rendered; the centre frequency's candidate range covers ±15% about both, {:.3}–{:.3} MHz, and it is scored from the better of the two by loss and from your scene's value alone, keeping the better score (a range bounds the search, and the spectra measure where to search; the image still decides whether it is named; `usray_signal::spectral_shift`).\n",
        sc.centre_hz / 1e6,
        sc.centre_std_hz / 1e6,
        (sc.centre_hz - sc.offset_hz) / 1e6,
        sc.range_hz[0] / 1e6,
        sc.range_hz[1] / 1e6,
    )
}

/// What the echoes' spectra showed of an attenuation where the image named
/// nothing ([`Diagnosis::spectral_attenuation`]).
fn spectral_attenuation_paragraph(
    r: &mut String,
    heading: &str,
    d: &Diagnosis,
    sa: &SpectralAttenuation,
) -> fmt::Result {
    let named = named_effect(d).filter(|_| sa.named);
    let reading = match named {
        Some(e) => format!(
            "so the medium's attenuation is named, at {} dB/(cm·MHz) (the scene's plus this). The image alone named nothing: the calibration's parameters, fitted to the image, may stand in for an attenuation's darkening. With the null refit's parameters and this attenuation, the held-out loss changes by {} against the null refit ({} over the seeds, ± {} over the image): what the image says of the value the spectra found, reported, not tested",
            short(e.params.get(&e.path).copied().unwrap_or(f64::NAN)),
            signed_percent(-e.excess.unwrap_or(0.0)),
            excess_text(e),
            e.excess_spatial_std.map_or("—".into(), |s| format!("{s:.3}")),
        ),
        None => format!(
            "not an attenuation of at least {:.0} standard errors: none is named",
            d.rule.min_spectral_z
        ),
    };
    writeln!(
        r,
        "**{heading}:** {}, {reading} (`usray_signal::spectral_shift`).\n",
        shift_text(
            &sa.shift,
            "your scene's, rendered as given before the calibration,"
        )
    )
}

/// A spectral shift against `model` (`"the null refit's model's"`) in words:
/// the echoes, their offset, their trend along the path, and the
/// attenuation that trend implies.
fn shift_text(shift: &SpectralShift, model: &str) -> String {
    let z = shift
        .attenuation_z()
        .map_or(String::new(), |z| format!(", {z:+.1} standard errors"));
    format!(
        "over {} echoes of the measured channel data, their mean frequency lies {:+.3} MHz from {model} and changes by {:+.3} MHz per cm of two-way path against it: as an attenuation beyond the model's (Kuc 1984: `α₀ = −slope / 2σ²`, σ² = {:.3} MHz² the measured spectrum's variance), {:+.2}{} dB/(cm·MHz){z}",
        shift.echoes.len(),
        shift.offset_hz / 1e6,
        shift.slope_hz_per_m / 1e6 / 100.0,
        shift.spectral_variance_hz2 / 1e12,
        shift.attenuation_db_cm_mhz,
        plus_minus(shift.attenuation_std),
    )
}

/// A fraction as a signed whole percentage, `+3%`, `−12%`, and `0%` for one
/// that rounds to zero (not `-0%`).
fn signed_percent(fraction: f64) -> String {
    let p = (100.0 * fraction).round();
    if p == 0.0 {
        "0%".into()
    } else {
        format!("{p:+.0}%")
    }
}

/// ` ± 0.007` for a standard error, nothing without one.
fn plus_minus(se: Option<f64>) -> String {
    se.map_or(String::new(), |se| format!(" ± {se:.3}"))
}

/// A refit's first-look excess with its seeds' standard error, `+0.018 ±
/// 0.007` (`—` when not refitted).
fn excess_text(e: &EffectResult) -> String {
    e.excess.map_or("—".into(), |x| {
        format!("{x:+.3}{}", plus_minus(e.excess_std))
    })
}

/// A refit's first-look excess in its seeds' standard errors, `2.7`.
fn first_look_z(e: &EffectResult) -> String {
    match (e.excess, e.excess_std) {
        (Some(x), Some(se)) => format!("{:.1}", x / se),
        _ => "—".into(),
    }
}

/// A value in its parameter's own unit, fixed-point where that reads well.
fn short(v: f64) -> String {
    if v == 0.0 || (1e-2..1e4).contains(&v.abs()) {
        format!("{v:.3}")
    } else {
        format!("{v:.3e}")
    }
}

/// [`short`] with its sign.
fn signed(v: f64) -> String {
    if v >= 0.0 {
        format!("+{}", short(v))
    } else {
        short(v)
    }
}

/// A calibrated base parameter further than this fraction from the scene's
/// value is pointed out in the report (section 1).
const FAR_FROM_SCENE: f64 = 0.1;

/// The scene's own value of the parameter at `path`, if it names one.
fn scene_value(scene: &Scene, path: &str) -> Option<f64> {
    scene.get(&scene.key(path).ok()?).ok()
}

/// `(calibrated − given)/|given|`, `None` where the scene's value is 0.
fn relative_change(given: f64, calibrated: f64) -> Option<f64> {
    (given != 0.0).then(|| (calibrated - given) / given.abs())
}

/// A standard deviation, or why there is none.
fn std_text(std: Option<f64>) -> String {
    std.map_or("not determined".into(), |s| format!("{s:.2e}"))
}

/// `Some(x)` formatted by `f`, `—` for `None`.
fn or_dash(v: Option<f64>, f: impl Fn(f64) -> String) -> String {
    v.map_or("—".into(), f)
}

/// A Markdown table: a blank line, the header, the rule and one row per entry.
fn table(r: &mut String, header: &[&str], rows: Vec<Vec<String>>) -> fmt::Result {
    writeln!(
        r,
        "\n| {} |\n|{}",
        header.join(" | "),
        "---|".repeat(header.len())
    )?;
    for row in rows {
        writeln!(r, "| {} |", row.join(" | "))?;
    }
    Ok(())
}

/// The kinds of residual (echo position, amplitude, width, texture) as tables.
fn residual_kinds(r: &mut String, k: &ResidualReport) -> fmt::Result {
    let mm = |v: Option<f64>, sign: bool| {
        or_dash(v, |v| {
            if sign {
                format!("{:+.3}", 1e3 * v)
            } else {
                format!("{:.3}", 1e3 * v)
            }
        })
    };
    let db = |v: Option<f64>| or_dash(v, |v| format!("{v:+.2}"));
    writeln!(
        r,
        "\nKinds of residual (also in `diagnosis.json`, `residual_kinds`):"
    )?;
    table(
        r,
        &[
            "echo position in",
            "shift (measured deeper +), mm",
            "correlation once aligned",
        ],
        k.echo_position
            .iter()
            .map(|e| {
                let limit = if e.at_search_limit {
                    " (at the search limit)"
                } else {
                    ""
                };
                vec![
                    e.region.clone(),
                    format!("{}{limit}", mm(e.shift_m, true)),
                    or_dash(e.correlation, |v| format!("{v:.2}")),
                ]
            })
            .collect(),
    )?;
    table(
        r,
        &[
            "echo amplitude in",
            "pixels",
            "mean level, simulated − measured, dB",
            "echo energy, simulated / measured, dB",
        ],
        k.echo_amplitude
            .iter()
            .map(|e| {
                vec![
                    e.region.clone(),
                    e.pixels.to_string(),
                    db(e.mean_db_difference),
                    db(e.energy_db_difference),
                ]
            })
            .collect(),
    )?;
    table(
        r,
        &[
            "boundary width (echo FWHM) of",
            "simulated, mm",
            "measured, mm",
            "columns (sim / meas)",
        ],
        k.boundary_width
            .iter()
            .map(|e| {
                vec![
                    e.region.clone(),
                    mm(e.simulated_fwhm_m, false),
                    mm(e.measured_fwhm_m, false),
                    format!("{} / {}", e.simulated_columns, e.measured_columns),
                ]
            })
            .collect(),
    )?;
    let stats = |g: &Option<GreyStats>| match g {
        Some(g) => vec![
            format!("{:.3}", g.mean_grey),
            format!("{:.3}", g.std_grey),
            or_dash(g.speckle_snr, |v| format!("{v:.2}")),
            format!("{:.0}%", 100.0 * g.clipped_fraction),
        ],
        None => vec!["—".into(); 4],
    };
    table(
        r,
        &[
            "texture in",
            "pixels",
            "image",
            "mean grey",
            "grey std",
            "speckle SNR",
            "clipped",
        ],
        k.texture
            .iter()
            .flat_map(|e| {
                [("simulated", &e.simulated), ("measured", &e.measured)].map(|(which, g)| {
                    [
                        vec![e.region.clone(), e.pixels.to_string(), which.into()],
                        stats(g),
                    ]
                    .concat()
                })
            })
            .collect(),
    )?;
    writeln!(r, "\n(Speckle SNR is 1.91 for fully developed speckle; clipped: pixels below the dynamic range.)")
}

#[cfg(test)]
mod tests {
    use super::{signed_percent, width_beside_centre_paragraph};
    use crate::diagnosis::results::{EffectResult, SpectralCentre};
    use std::collections::BTreeMap;

    fn width_found(w_m: f64) -> EffectResult {
        let path = "probe.element_width_m".to_string();
        EffectResult {
            effect: "element_width".into(),
            path: path.clone(),
            score: 0.02,
            onset: 0.27e-3,
            range: [0.1e-3, 0.3e-3],
            null: Some(0.27e-3),
            gradient: 1.0,
            loss_onset: 3e-2,
            loss_after: Some(2.9e-2),
            shrink: Some(0.04),
            shrink_std: Some(0.004),
            excess: Some(0.04),
            excess_std: Some(0.004),
            excess_spatial_std: Some(0.009),
            gap_explained: Some(0.04),
            held_out_losses: vec![],
            params: BTreeMap::from([(path, w_m)]),
            params_std: BTreeMap::new(),
            detection_limit: None,
            tolerance: None,
            absence_cost: None,
            absence_cost_std: None,
            additivity: None,
            failed: None,
            confirmation: None,
            spectral_z: None,
            more_rays: None,
        }
    }

    fn centre(offset_hz: f64) -> SpectralCentre {
        SpectralCentre {
            centre_hz: 2.5e6 + offset_hz,
            centre_std_hz: 5e3,
            offset_hz,
            range_hz: [2.1e6, 3.1e6],
        }
    }

    #[test]
    fn a_width_is_offered_as_the_centre_frequencys_trade_only_where_it_moved_its_way() {
        // w·f sets the directivity: a narrower element hears as a lower centre does.
        let mut r = String::new();
        width_beside_centre_paragraph(&mut r, &width_found(0.2e-3), &centre(-0.2e6)).unwrap();
        assert!(
            r.contains("An element width, or a centre frequency?"),
            "{r}"
        );
        // A narrower element for a higher centre is not that centre's directivity.
        let mut r = String::new();
        width_beside_centre_paragraph(&mut r, &width_found(0.12e-3), &centre(0.16e6)).unwrap();
        assert!(
            r.contains("is not that centre frequency's") && r.contains("0.120 mm for 0.270"),
            "{r}"
        );
        // A wider element for a lower centre neither.
        let mut r = String::new();
        width_beside_centre_paragraph(&mut r, &width_found(0.3e-3), &centre(-0.1e6)).unwrap();
        assert!(
            r.contains("a wider element") && r.contains("hears narrower"),
            "{r}"
        );
    }

    #[test]
    fn a_change_that_rounds_to_zero_has_no_sign() {
        assert_eq!(signed_percent(-0.0004), "0%");
        assert_eq!(signed_percent(0.0004), "0%");
        assert_eq!(signed_percent(0.031), "+3%");
        assert_eq!(signed_percent(-0.12), "-12%");
    }
}
