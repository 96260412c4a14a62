//! `motile stability onset`: where the particle model starts to behave like the continuum
//! (docs/MODEL.md §5, §5b). For each volume fraction `nu` and each box (values of `L nu`, or box
//! sides given directly), a particle run from the same seeded perturbation of the continuum's
//! initial field (box-scale modes, `|m| = 1`), its box-scale velocity fitted for a growth rate;
//! with a flow, the amplitudes of the lowest box modes (`modes.csv`) are fitted for a complex
//! rate (the lowest mode beats between the onset and `L/l` about 87 at `nu = 0.625`), and the
//! rods' effective rotational diffusion is measured from their orientation autocorrelation
//! `<p(t).p(0)> = exp(-2 d_r t)`. The table sets each beside the linear theory of the box
//! ([`motile_particle::model::linear_theory`]) without diffusion and with the measured `d_r`.
//! The chart shows `gamma / nu` against `L nu` (growth rates scale with `nu`, the onset box
//! with `1/nu`), beside the continuum's rate (M3) in the same units and the box theory's.

use crate::io::rundir::TimeSeries;
use crate::io::write_atomic;
use crate::report::curves::{MIN_GROWTH_FACTOR, MIN_R_SQUARED, nan_growth_fit};
use crate::report::plot::{Chart, Series, line_chart};
use crate::run::particle::{self, ParticleRunConfig, PerturbationConfig};
use anyhow::Context;
use motile_analysis::stats::{ComplexRateFit, GrowthFit, fit_complex_rate, growth_phase};
use motile_particle::model::level::Hydrodynamics;
use motile_particle::model::linear_theory::{growth_rate, lowest_mode};
use motile_particle::model::units::{
    DEFAULT_DIAMETER, SWIM_SPEED, continuum_growth_rate, meanfield_time_unit, zeta,
};
use std::fmt::Write as _;
use std::path::Path;

/// Settings of an onset scan.
#[derive(Clone, Debug, PartialEq)]
pub struct OnsetOptions {
    /// Volume fractions.
    pub fractions: Vec<f64>,
    /// Values of `L nu` (the box side of each run is `L nu / nu`, rounded to a tenth).
    pub box_nu: Vec<f64>,
    /// The hydrodynamic level (a flow is needed: Dipole or Sbt).
    pub hydrodynamics: Hydrodynamics,
    /// Time step (1/beta).
    pub dt: f64,
    /// End time times `nu` (each run ends at `t_end_nu / nu`, the same number of continuum
    /// time units).
    pub t_end_nu: f64,
    /// Amplitude of the seeded perturbation (largest component of `Q'`).
    pub amplitude: f64,
    /// Fast-sum tolerance.
    pub sum_tolerance: f64,
    /// Box sides (rod lengths) to run at every volume fraction, in place of `box_nu` when not
    /// empty.
    pub boxes: Vec<f64>,
    /// End time (1/beta) in place of `t_end_nu / nu`.
    pub t_end: Option<f64>,
    /// Time between snapshots (1/beta), which the rotational diffusion is measured from; by
    /// default only the first and last.
    pub snapshot_interval: Option<f64>,
    /// Contact margin (rod lengths); the default's where `None`.
    pub contact_margin: Option<f64>,
    /// With fixed boxes: run each box at least this many periods of its lowest mode where the
    /// box theory (no diffusion) makes it a complex pair, `periods 2 pi / |Im sigma|`, if that
    /// is longer than the end time.
    pub periods: Option<f64>,
}

impl Default for OnsetOptions {
    fn default() -> Self {
        Self {
            fractions: vec![3.75, 5.0],
            box_nu: vec![30.0, 45.0, 60.0],
            hydrodynamics: Hydrodynamics::Sbt,
            dt: 0.04,
            t_end_nu: 40.0,
            amplitude: 0.025,
            sum_tolerance: 1e-2,
            boxes: Vec::new(),
            t_end: None,
            snapshot_interval: None,
            contact_margin: None,
            periods: None,
        }
    }
}

/// One run of the scan.
#[derive(Clone, Debug, PartialEq)]
pub struct OnsetPoint {
    /// Volume fraction.
    pub nu: f64,
    /// Box side (l).
    pub box_length: f64,
    /// Rods.
    pub rods: usize,
    /// The fit of the box-scale velocity norm (rate in 1/beta).
    pub fit: Option<GrowthFit>,
    /// Whether the fit is a growth phase (grew by 3 with R^2 >= 0.9).
    pub grew: bool,
    /// The complex rate fitted to the lowest box modes (runs with a flow).
    pub complex: Option<ComplexRateFit>,
    /// The effective rotational diffusion (1/beta) from `<p(t).p(0)> = exp(-2 d_r t)` over the
    /// snapshots before the flow saturates; `None` without enough snapshots.
    pub rotational_diffusion: Option<f64>,
    /// Wall seconds.
    pub seconds: f64,
}

/// The continuum's growth rate (M3, `D = 0`) in particle units at volume fraction `nu` for
/// rods of diameter `b`: `(1/5)/(1 + zeta/15) nu/(8 eta mu)`, `zeta = nu/(24 eta mu)`.
pub fn continuum_rate(nu: f64, diameter: f64) -> f64 {
    continuum_growth_rate(zeta(nu, diameter)) / meanfield_time_unit(nu, diameter)
}

/// The growth rate of a box-scale norm series: its growth phase if it has one (the criterion of
/// `motile compare`), else the fit over the whole series (a decay or a flat line).
pub fn box_scale_fit(t: &[f64], u: &[f64]) -> (Option<GrowthFit>, bool) {
    match growth_phase(t, u, MIN_GROWTH_FACTOR, MIN_R_SQUARED) {
        Some((g, grew)) => (Some(g), grew),
        None => (None, false),
    }
}

/// Run the scan into `out` (one run directory per point, then `onset.{png,svg,csv,md}`).
pub fn onset(
    opts: &OnsetOptions,
    out: &Path,
    mut event: impl FnMut(&str),
) -> anyhow::Result<Vec<OnsetPoint>> {
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    let mut points = Vec::new();
    for &nu in &opts.fractions {
        for l in box_sides(opts, nu) {
            let t_end = run_length(opts, nu, l);
            let cfg = point_config(opts, nu, l, t_end);
            let dir = out.join(format!("nu{nu}_L{l}"));
            let run = run_or_reuse(&cfg, &dir)?;
            let measured = measure(&dir, t_end, l)?;
            report_point(&mut event, nu, l, &run, &measured);
            points.push(OnsetPoint {
                nu,
                box_length: l,
                rods: run.rods,
                fit: measured.fit,
                grew: measured.grew,
                complex: measured.complex,
                rotational_diffusion: measured.rotational_diffusion,
                seconds: run.seconds,
            });
        }
    }
    write_onset(&points, opts, out)?;
    Ok(points)
}

/// The box sides run at volume fraction `nu`: the given boxes, or `L nu / nu` for each value of
/// `L nu`, rounded to a tenth.
fn box_sides(opts: &OnsetOptions, nu: f64) -> Vec<f64> {
    if opts.boxes.is_empty() {
        opts.box_nu
            .iter()
            .map(|lnu| (10.0 * lnu / nu).round() / 10.0)
            .collect()
    } else {
        opts.boxes.clone()
    }
}

/// The config of the run at volume fraction `nu` in the box `l` to `t_end`: the seeded
/// box-scale perturbation, diagnostics about 40 per run (a scan over `L nu`, the earlier scans'
/// cadence: their runs are reused as they are) or every half time unit (fixed boxes, for the
/// complex fits).
fn point_config(opts: &OnsetOptions, nu: f64, l: f64, t_end: f64) -> ParticleRunConfig {
    let mut cfg = ParticleRunConfig {
        box_length: l,
        volume_fraction: nu,
        dt: opts.dt,
        t_end,
        hydrodynamics: opts.hydrodynamics,
        initial: "perturbation".into(),
        perturbation: PerturbationConfig {
            amplitude: opts.amplitude,
            mode_min: 1,
            mode_max: 1,
            ..PerturbationConfig::default()
        },
        diagnostic_interval: (t_end / 40.0 / opts.dt).round().max(1.0) * opts.dt,
        snapshot_interval: opts.snapshot_interval.unwrap_or(t_end),
        checkpoint_interval: t_end,
        vtk: false,
        lowest_modes: opts.hydrodynamics.has_flow(),
        ..ParticleRunConfig::default()
    };
    if !opts.boxes.is_empty() {
        cfg.diagnostic_interval = (0.5 / opts.dt).round().max(1.0) * opts.dt;
    }
    match opts.contact_margin {
        Some(m) => cfg.contact.margin = m,
        // Left out, the margin follows the step where it must (2.5 U dt).
        None => cfg.contact.margin = cfg.contact.margin.max(2.5 * opts.dt),
    }
    cfg.hydro.sum_tolerance = opts.sum_tolerance;
    cfg
}

/// One point's run: its rods and wall time, and whether an earlier run was reused.
struct PointRun {
    rods: usize,
    seconds: f64,
    reused: bool,
}

/// Run `cfg` into `dir`, or reuse a finished run there with the same settings (a scan can be
/// extended or re-charted without running its cells again); anything else is run afresh. The
/// wall time is kept in `onset_seconds.txt`.
fn run_or_reuse(cfg: &ParticleRunConfig, dir: &Path) -> anyhow::Result<PointRun> {
    let seconds_file = dir.join("onset_seconds.txt");
    let (nu, l) = (cfg.volume_fraction, cfg.box_length);
    let finished =
        crate::io::rundir::read_run_config::<ParticleRunConfig>(dir, ParticleRunConfig::validate)
            // Both resolved: defaults that follow other keys (the RPY radius) filled in.
            .is_ok_and(|c| c.resolved() == cfg.resolved())
            && TimeSeries::read(&dir.join("timeseries.csv")).is_ok_and(|ts| {
                ts.column("t [1/beta]")
                    .and_then(|t| t.last().copied())
                    .is_some_and(|t| t > cfg.t_end - cfg.diagnostic_interval)
            });
    if finished {
        let seconds = std::fs::read_to_string(&seconds_file)
            .ok()
            .and_then(|s| s.trim().parse().ok())
            .unwrap_or(f64::NAN);
        return Ok(PointRun {
            rods: (nu * l * l * l).round() as usize,
            seconds,
            reused: true,
        });
    }
    crate::io::remove_old_run(dir)?;
    let t = std::time::Instant::now();
    let summary = particle::run_particle(cfg, dir, false)
        .with_context(|| format!("onset run nu = {nu}, L/l = {l}"))?;
    let seconds = t.elapsed().as_secs_f64();
    write_atomic(&seconds_file, format!("{seconds}\n").as_bytes())?;
    Ok(PointRun {
        rods: summary.rods.len(),
        seconds,
        reused: false,
    })
}

/// What a point's run measured.
struct Measured {
    fit: Option<GrowthFit>,
    grew: bool,
    complex: Option<ComplexRateFit>,
    rotational_diffusion: Option<f64>,
}

/// Fit the run in `dir` (box `l`, to `t_end`): its box-scale norm's growth; until the flow
/// saturates, its lowest modes' complex rate and, before that and the run's half, the rods'
/// rotational diffusion.
fn measure(dir: &Path, t_end: f64, l: f64) -> anyhow::Result<Measured> {
    let ts = TimeSeries::read(&dir.join("timeseries.csv"))?;
    let time = ts.column("t [1/beta]").context("time column")?;
    let u = ts
        .column("velocity_norm_box [beta L]")
        .context("box-scale velocity column")?;
    let (fit, grew) = box_scale_fit(&time, &u);
    let saturated = saturation_time(&time, &u, t_end);
    let complex = complex_fit(dir, saturated, l)?;
    let rotational_diffusion =
        crate::report::curves::rotational_diffusion(dir, saturated.min(0.5 * t_end))?;
    Ok(Measured {
        fit,
        grew,
        complex,
        rotational_diffusion,
    })
}

/// Where the flow saturates: its box norm past a quarter of its largest value after growing
/// tenfold; else the end of the run.
fn saturation_time(time: &[f64], u: &[f64], t_end: f64) -> f64 {
    let u_max = u.iter().copied().fold(0.0, f64::max);
    if u_max > 10.0 * u.first().copied().unwrap_or(u_max) {
        time.iter()
            .zip(u)
            .find(|(_, v)| **v > 0.25 * u_max)
            .map_or(t_end, |(t, _)| *t)
    } else {
        t_end
    }
}

/// The lines a point gives `event`: its fit, and its lowest modes' rate where fitted.
fn report_point(event: &mut impl FnMut(&str), nu: f64, l: f64, run: &PointRun, m: &Measured) {
    event(&format!(
        "nu = {nu}, L/l = {l} ({} rods, {:.0} s{}): {}",
        run.rods,
        run.seconds,
        if run.reused { ", done already" } else { "" },
        m.fit.as_ref().map_or("no fit".into(), |g| format!(
            "rate {:.4} +- {:.4} per 1/beta over [{:.2}, {:.2}], R^2 {:.2}, grew x{:.2}{}",
            g.rate,
            g.std_error,
            g.t0,
            g.t1,
            g.r_squared,
            g.growth_factor,
            if m.grew { " (growth phase)" } else { "" }
        ))
    ));
    if let Some(c) = &m.complex {
        event(&format!(
            "    lowest modes: sigma = {:.4} {:+.4} i over [{:.1}, {:.1}] (R^2 {:.3}); d_r = {}",
            c.sigma.re,
            c.sigma.im,
            c.t0,
            c.t1,
            c.r_squared,
            m.rotational_diffusion
                .map_or("-".into(), |d| format!("{d:.2e}"))
        ));
    }
}

/// The complex rate of the lowest box modes of the run in `dir` (its `modes.csv`) up to `t1`.
fn complex_fit(dir: &Path, t1: f64, box_length: f64) -> anyhow::Result<Option<ComplexRateFit>> {
    let path = dir.join("modes.csv");
    if !path.exists() {
        return Ok(None);
    }
    let ts = TimeSeries::read(&path)?;
    let t = ts.column("t [1/beta]").context("modes.csv: time column")?;
    // One series per mode and flow component: columns 1 + 2 k (re) and 2 + 2 k (im).
    let series: Vec<Vec<num_complex::Complex64>> = (0..9)
        .map(|k| {
            ts.rows
                .iter()
                .map(|r| num_complex::Complex64::new(r[1 + 2 * k], r[2 + 2 * k]))
                .collect()
        })
        .filter(|s: &Vec<num_complex::Complex64>| s.iter().any(|z| z.norm() > 0.0))
        .collect();
    // The lowest mode's frequencies lie below the free-streaming k U = 2 pi U / L (the edge of
    // the continuous spectrum): the recurrence's lag must resolve them.
    let free_streaming = 2.0 * std::f64::consts::PI * SWIM_SPEED / box_length;
    Ok(fit_complex_rate(&t, &series, 0.0, t1, free_streaming))
}

/// How long the run of box `l` at `nu` lasts: the end time, or with `opts.periods` the
/// theory's periods of the lowest mode if longer (rounded up to a whole 10/beta).
fn run_length(opts: &OnsetOptions, nu: f64, l: f64) -> f64 {
    let base = opts.t_end.unwrap_or(opts.t_end_nu / nu);
    match (opts.periods, theory(nu, l, 0.0)) {
        (Some(p), Some(s)) if s.im.abs() > 1e-9 && !opts.boxes.is_empty() => {
            base.max((p * 2.0 * std::f64::consts::PI / s.im.abs() / 10.0).ceil() * 10.0)
        }
        _ => base,
    }
}

/// The linear theory's dominant rate of the lowest box mode (`None` where it is damped).
fn theory(nu: f64, box_length: f64, d_r: f64) -> Option<num_complex::Complex64> {
    growth_rate(nu, DEFAULT_DIAMETER, lowest_mode(box_length), d_r).map(|g| g.sigma)
}

/// The table and charts of a scan over box sides at fixed volume fractions: each run's
/// lowest-mode complex rate beside the box theory's, without diffusion and with the rotational
/// diffusion measured in the runs.
fn write_box_scan(points: &[OnsetPoint], opts: &OnsetOptions, out: &Path) -> anyhow::Result<()> {
    let mut csv = String::from(
        "nu,L/l,rods,sigma_re,sigma_im,modes_r_squared,t0,t1,box_rate,box_r_squared,box_growth_factor,d_r,theory_re,theory_im,theory_dr_re,theory_dr_im,seconds\n",
    );
    let mut md = format!(
        "# Growth of the lowest box mode ({} model)\n\nEach run starts from the same seeded perturbation of the isotropic state (box-scale modes |m| = 1, amplitude {}). Measured: the complex rate of the lowest box modes' flow amplitudes (modes.csv; a two-rate linear recurrence shared by the three modes and their components, fitted from the start until the box-scale norm passes a quarter of its largest value, its lag at most a quarter period of the free-streaming frequency 2 pi U/L so that no frequency of the mode aliases), and the rods' rotational diffusion from <p(t).p(0)> = exp(-2 d_r t) over the snapshots before that. Theory: the dispersion relation of docs/MODEL.md §5b for the lowest mode k = 2 pi/L, without diffusion and with the measured d_r. Rates in 1/beta.\n\n| nu | L/l | rods | measured sigma | R^2 | window | box-norm growth | d_r | theory (d_r = 0) | theory (measured d_r) | Re: measured / theory | wall (s) |\n|---|---|---|---|---|---|---|---|---|---|---|---|\n",
        opts.hydrodynamics, opts.amplitude
    );
    for p in points {
        let theories = BoxTheories::of(p);
        csv.push_str(&box_scan_csv_row(p, &theories));
        md.push_str(&box_scan_md_row(p, &theories));
    }
    write_atomic(&out.join("onset.csv"), csv.as_bytes())?;
    write_atomic(&out.join("onset.md"), md.as_bytes())?;
    write_box_scan_charts(points, opts, out)
}

/// A point's box theory without diffusion and with the rotational diffusion measured in it
/// (none where not measured).
struct BoxTheories {
    without_diffusion: Option<num_complex::Complex64>,
    with_diffusion: Option<num_complex::Complex64>,
}

impl BoxTheories {
    fn of(p: &OnsetPoint) -> Self {
        let d_r = p.rotational_diffusion.unwrap_or(0.0).max(0.0);
        Self {
            without_diffusion: theory(p.nu, p.box_length, 0.0),
            with_diffusion: theory(p.nu, p.box_length, d_r),
        }
    }
}

/// A complex rate as the table writes it, or "damped".
fn complex_cell(z: Option<num_complex::Complex64>) -> String {
    z.map_or("damped".into(), |z| format!("{:.4} {:+.4}i", z.re, z.im))
}

fn box_scan_csv_row(p: &OnsetPoint, theories: &BoxTheories) -> String {
    let c = p.complex;
    let sigma = c.map(|c| c.sigma);
    let (th, thd) = (theories.without_diffusion, theories.with_diffusion);
    format!(
        "{},{},{},{:e},{:e},{},{},{},{:e},{},{},{:e},{:e},{:e},{:e},{:e},{:.1}\n",
        p.nu,
        p.box_length,
        p.rods,
        sigma.map_or(f64::NAN, |z| z.re),
        sigma.map_or(f64::NAN, |z| z.im),
        c.map_or(f64::NAN, |c| c.r_squared),
        c.map_or(f64::NAN, |c| c.t0),
        c.map_or(f64::NAN, |c| c.t1),
        p.fit.as_ref().map_or(f64::NAN, |g| g.rate),
        p.fit.as_ref().map_or(f64::NAN, |g| g.r_squared),
        p.fit.as_ref().map_or(f64::NAN, |g| g.growth_factor),
        p.rotational_diffusion.unwrap_or(f64::NAN),
        th.map_or(f64::NAN, |z| z.re),
        th.map_or(f64::NAN, |z| z.im),
        thd.map_or(f64::NAN, |z| z.re),
        thd.map_or(f64::NAN, |z| z.im),
        p.seconds
    )
}

fn box_scan_md_row(p: &OnsetPoint, theories: &BoxTheories) -> String {
    let c = p.complex;
    let sigma = c.map(|c| c.sigma);
    let ratio = match (sigma, theories.without_diffusion) {
        (Some(m), Some(t)) if t.re > 0.0 => format!("{:.2}", m.re / t.re),
        _ => "-".into(),
    };
    format!(
        "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {ratio} | {:.0} |\n",
        p.nu,
        p.box_length,
        p.rods,
        complex_cell(sigma),
        c.map_or("-".into(), |c| format!("{:.3}", c.r_squared)),
        c.map_or("-".into(), |c| format!("{:.0}-{:.0}", c.t0, c.t1)),
        p.fit.as_ref().map_or("-".into(), |g| format!(
            "x{:.1}, R^2 {:.2}{}",
            g.growth_factor,
            g.r_squared,
            if p.grew { " (growth phase)" } else { "" }
        )),
        p.rotational_diffusion
            .map_or("-".into(), |d| format!("{d:.1e}")),
        complex_cell(theories.without_diffusion),
        complex_cell(theories.with_diffusion),
        p.seconds
    )
}

/// The mean of the rotational diffusion measured in the runs (0 where none was, and at least
/// 0).
fn mean_rotational_diffusion(points: &[OnsetPoint]) -> f64 {
    let d: Vec<f64> = points
        .iter()
        .filter_map(|p| p.rotational_diffusion)
        .collect();
    if d.is_empty() {
        0.0
    } else {
        (d.iter().sum::<f64>() / d.len() as f64).max(0.0)
    }
}

/// Charts of a box scan: the real and imaginary parts of the lowest mode's rate against L/l,
/// the box theory (without diffusion and with the mean measured d_r) as curves.
fn write_box_scan_charts(
    points: &[OnsetPoint],
    opts: &OnsetOptions,
    out: &Path,
) -> anyhow::Result<()> {
    for (stem, title, y_label, part) in [
        (
            "onset",
            "Growth rate of the lowest box mode against the box (nu fixed)",
            "Re sigma [beta]",
            0,
        ),
        (
            "onset_frequency",
            "Frequency of the lowest box mode (its norm beats at 2 Im sigma)",
            "Im sigma [beta]",
            1,
        ),
    ] {
        let pick = |z: num_complex::Complex64| if part == 0 { z.re } else { z.im };
        line_chart(
            &out.join(stem),
            &Chart {
                title,
                x_label: "box side L/l",
                y_label,
                series: box_scan_series(points, opts, pick),
            },
        )?;
    }
    Ok(())
}

/// One box-scan chart's series: per volume fraction the runs' `pick` of their lowest-mode rate
/// and the box theory's over the boxes' range, without diffusion and with the mean measured d_r.
fn box_scan_series(
    points: &[OnsetPoint],
    opts: &OnsetOptions,
    pick: impl Fn(num_complex::Complex64) -> f64,
) -> Vec<Series> {
    let (lo, hi) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
        (a.min(p.box_length), b.max(p.box_length))
    });
    let d_mean = mean_rotational_diffusion(points);
    let mut series = Vec::new();
    for &nu in &opts.fractions {
        series.push(Series {
            label: format!(
                "particles, nu = {nu} ({}, lowest modes)",
                opts.hydrodynamics
            ),
            points: points
                .iter()
                .filter(|p| p.nu == nu)
                .filter_map(|p| p.complex.map(|c| (p.box_length, pick(c.sigma))))
                .collect(),
        });
        for (d, label) in [
            (0.0, format!("box theory, nu = {nu}, no diffusion")),
            (
                d_mean,
                format!("box theory, nu = {nu}, d_r = {d_mean:.1e} (measured)"),
            ),
        ] {
            series.push(Series {
                label,
                points: (0..=80)
                    .map(|k| lo + (hi - lo) * k as f64 / 80.0)
                    .filter_map(|l| theory(nu, l, d).map(|z| (l, pick(z))))
                    .collect(),
            });
        }
    }
    series
}

/// The table and chart of the scan (`onset.{csv,md,png,svg}`): over `L nu` at each volume
/// fraction, or, with fixed boxes, [`write_box_scan`].
fn write_onset(points: &[OnsetPoint], opts: &OnsetOptions, out: &Path) -> anyhow::Result<()> {
    if !opts.boxes.is_empty() {
        return write_box_scan(points, opts, out);
    }
    let mut csv = String::from(
        "nu,L/l,L nu,rods,rate [1/beta],rate_std_error,rate/nu,continuum_rate/nu,r_squared,growth_factor,growth_phase,t0,t1,seconds\n",
    );
    let mut md = format!(
        "# Onset of the instability ({} model)\n\nEach run starts from the same seeded perturbation of the isotropic state (box-scale modes |m| = 1, amplitude {}), the rods' orientations drawn from it (docs/MODEL.md §5); the growth rate is a least-squares fit of the logarithm of the box-scale velocity norm, and its peak local rate (charted), over its growth phase (from the start to where the local rate falls below 40% of its largest value, grown at least 3 times with R^2 >= 0.9) or, without one, over the whole run. Continuum: (M3) with D = 0, in particle units.\n\n| nu | L/l | L nu | rods | rate (1/beta) | peak rate / nu | continuum / nu | growth phase | R^2 | grew by | wall (s) |\n|---|---|---|---|---|---|---|---|---|---|---|\n",
        opts.hydrodynamics, opts.amplitude
    );
    for p in points {
        write_onset_rows(p, &mut csv, &mut md);
    }
    write_atomic(&out.join("onset.csv"), csv.as_bytes())?;
    write_atomic(&out.join("onset.md"), md.as_bytes())?;
    line_chart(
        &out.join("onset"),
        &Chart {
            title: "Growth rate of the box-scale flow over nu, against L nu (docs/MODEL.md section 5)",
            x_label: "L nu [l]",
            y_label: "peak growth rate / nu [beta]",
            series: onset_series(points, opts),
        },
    )?;
    Ok(())
}

/// One point's rows of `onset.csv` and `onset.md`: its fit beside the continuum's rate.
fn write_onset_rows(p: &OnsetPoint, csv: &mut String, md: &mut String) {
    let c = continuum_rate(p.nu, DEFAULT_DIAMETER) / p.nu;
    let g = p.fit.unwrap_or_else(nan_growth_fit);
    let (rate, err, r2, gf, t0, t1) = (
        g.rate,
        g.std_error,
        g.r_squared,
        g.growth_factor,
        g.t0,
        g.t1,
    );
    writeln!(
        csv,
        "{},{},{},{},{rate:e},{err:e},{:e},{c:e},{r2},{gf},{},{t0},{t1},{:.1}",
        p.nu,
        p.box_length,
        p.box_length * p.nu,
        p.rods,
        rate / p.nu,
        p.grew,
        p.seconds
    )
    .expect("string");
    writeln!(
        md,
        "| {} | {} | {:.1} | {} | {rate:.4} +- {err:.4} | {:.4} | {c:.4} | {} | {r2:.2} | {gf:.2} | {:.0} |",
        p.nu,
        p.box_length,
        p.box_length * p.nu,
        p.rods,
        g.peak_rate / p.nu,
        if p.grew { "yes" } else { "no" },
        p.seconds
    )
    .expect("string");
}

/// The chart's series: each volume fraction's peak rates over nu against `L nu`, then the
/// continuum's rate over nu as flat lines.
fn onset_series(points: &[OnsetPoint], opts: &OnsetOptions) -> Vec<Series> {
    let mut series: Vec<Series> = Vec::new();
    let (x_lo, x_hi) = points.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
        let x = p.box_length * p.nu;
        (a.min(x), b.max(x))
    });
    for &nu in &opts.fractions {
        series.push(Series {
            label: format!("particles, nu = {nu} ({})", opts.hydrodynamics),
            points: points
                .iter()
                .filter(|p| p.nu == nu)
                .filter_map(|p| {
                    p.fit
                        .as_ref()
                        .map(|g| (p.box_length * nu, g.peak_rate / nu))
                })
                .collect(),
        });
    }
    for &nu in &opts.fractions {
        let c = continuum_rate(nu, DEFAULT_DIAMETER) / nu;
        series.push(Series {
            label: format!("continuum (M3, D = 0), nu = {nu}"),
            points: vec![(x_lo, c), (x_hi, c)],
        });
    }
    series
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn continuum_rate_is_the_linear_theory_in_particle_units() {
        // nu = 0.625: zeta = 0.1421, gamma = 0.2/(1 + zeta/15) = 0.19812, times nu/(8 eta).
        let r = continuum_rate(0.625, DEFAULT_DIAMETER);
        assert!((r - 0.19812 * 0.625 / (8.0 * 0.183234)).abs() < 1e-4, "{r}");
    }

    #[test]
    fn runs_last_the_asked_periods_of_the_lowest_mode() {
        let opts = OnsetOptions {
            boxes: vec![20.0, 32.0, 50.0, 100.0],
            t_end: Some(100.0),
            periods: Some(2.0),
            ..OnsetOptions::default()
        };
        // L/l = 50: sigma = 0.02774 +- 0.06456 i, two periods 194.6 -> 200; L/l = 32: 106.8
        // -> 110; damped (20) and real (100) boxes keep the end time.
        let t: Vec<f64> = [20.0, 32.0, 50.0, 100.0]
            .iter()
            .map(|&l| run_length(&opts, 0.625, l))
            .collect();
        assert_eq!(t, vec![100.0, 110.0, 200.0, 100.0]);
        let plain = OnsetOptions {
            periods: None,
            ..opts
        };
        assert_eq!(run_length(&plain, 0.625, 50.0), 100.0);
    }

    #[test]
    fn a_growth_phase_needs_growth_and_a_good_fit() {
        let t: Vec<f64> = (0..40).map(|k| k as f64 * 0.5).collect();
        // Grows at 0.3, then saturates at 50 x the start.
        let u: Vec<f64> = t.iter().map(|t| (0.3f64 * t).exp().min(50.0)).collect();
        let (g, grew) = box_scale_fit(&t, &u);
        let g = g.unwrap();
        // Its peak local rate is the rate; the fit over the phase reaches just past the bend.
        assert!(
            grew && (g.peak_rate - 0.3).abs() < 1e-9 && (g.rate - 0.3).abs() < 0.01 * 0.3,
            "{g:?}"
        );
        // A flat noisy series is no growth phase.
        let flat: Vec<f64> = t
            .iter()
            .enumerate()
            .map(|(k, _)| 1.0 + 0.05 * ((k * 7919) % 13) as f64 / 13.0)
            .collect();
        let (g, grew) = box_scale_fit(&t, &flat);
        assert!(!grew && g.unwrap().rate.abs() < 0.02);
    }
}
