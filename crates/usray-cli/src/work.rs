//! The work estimate a run is checked against before it starts: past about a
//! minute of tracing or two of beamforming it asks for `--yes`.

use anyhow::Result;

/// Rays a run traces without `--yes`: about a minute at the 4·10⁶ rays/s one
/// core traces on the cylinder scene (`usray render`'s `rays_per_second`); the
/// shipped scenes' fits and diagnoses trace under 6·10⁷.
pub const MAX_RAYS_WITHOUT_YES: f64 = 2.4e8;

/// Delay-and-sum terms (pixels × elements × transmits, summed over the images
/// formed) a run computes without `--yes`: about two minutes at the 9·10⁷ per
/// second of one core (`docs/performance.md`, "delay-and-sum throughput"); a
/// 150-iteration fit of `scenes/cylinder.toml` forms 7.5·10⁹.
pub const MAX_DAS_TERMS_WITHOUT_YES: f64 = 1e10;

/// Refuses a run of `renders` renders of `scene` (with `opts`' overrides) whose
/// overrides pass the scene's limits, or whose traced rays pass
/// [`MAX_RAYS_WITHOUT_YES`] unless `yes`; the error states the estimate and
/// what to do. Each render is also beamformed ([`confirm_beamforming`]).
pub fn confirm_work(
    renders: f64,
    scene: &usray_transport::Scene,
    opts: &usray_transport::RenderOptions,
    yes: bool,
) -> Result<()> {
    // The overrides within the scene's limits first: past them no `--yes` helps.
    opts.check(scene)?;
    let rays = opts
        .rays_per_element
        .unwrap_or(scene.acquisition.rays_per_element) as f64;
    let channels = scene.probe.n_elements as f64 * scene.n_transmits() as f64;
    let per_render = channels * rays;
    let total = renders * per_render;
    anyhow::ensure!(
        yes || total <= MAX_RAYS_WITHOUT_YES,
        "this run would trace about {total:.1e} rays ({renders:.0} render(s) of {per_render:.1e}: elements × transmits × rays per element), at least {:.2} core-hours at 4e6 rays/s; lower the rays (--rays) or pass --yes to run it",
        total / 4e6 / 3600.0
    );
    confirm_beamforming(renders, usray_optim::grid_shape(scene)?, channels, yes)
}

/// Refuses forming `images` B-modes of `(nz, nx)` pixels from `channels` records
/// (elements × transmits) past [`MAX_DAS_TERMS_WITHOUT_YES`] unless `yes`.
pub fn confirm_beamforming(
    images: f64,
    (nz, nx): (usize, usize),
    channels: f64,
    yes: bool,
) -> Result<()> {
    let terms = images * (nz * nx) as f64 * channels;
    anyhow::ensure!(
        yes || terms <= MAX_DAS_TERMS_WITHOUT_YES,
        "this run would beamform about {terms:.1e} delay-and-sum terms ({images:.0} image(s) of {nz} × {nx} pixels from {channels:.0} records), at least {:.2} core-hours at 9e7 terms/s; use a coarser [imaging] pixel_m or pass --yes to run it",
        terms / 9e7 / 3600.0
    );
    Ok(())
}
