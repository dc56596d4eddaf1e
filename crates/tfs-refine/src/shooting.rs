//! The multiple-shooting stages of a refinement: the problems they share ([`Shooting`]), the
//! segments and their length, the scales of the unknowns, and the coefficients the stages carry
//! from one to the next ([`Progress`]).

use serde_json::json;

use crate::lm::{LmOutcome, LmSettings, Prepared, Problem, Segment, levenberg_marquardt};
use crate::refine::{RefineOptions, dominant_frequency};
use crate::sens::Structure;

/// A state beyond this many times its data RMS (`xs`, `vs`, `zs`) is taken as a blow-up.
const BLOW_UP_LIMIT: f64 = 1e6;

/// The shortest shooting segment (samples) that halving may reach.
const MIN_SEGMENT: usize = 4;

/// What every least-squares problem of one refinement shares: the model's structure, the
/// prepared records and the scales of the unknowns ([`Problem`]'s fields but the segments and
/// the continuity weight).
pub(crate) struct Shooting<'a> {
    pub st: &'a Structure,
    pub recs: &'a [Prepared],
    pub pscale: Vec<f64>,
    pub xs: Vec<f64>,
    pub vs: Vec<f64>,
    pub zs: Vec<f64>,
    pub substeps: usize,
}

impl<'a> Shooting<'a> {
    /// The problem over segments of `seg_len` samples (one per record when `single`) with
    /// continuity-defect weight `defect_weight`.
    fn problem(&self, single: bool, seg_len: usize, defect_weight: f64) -> Problem<'a> {
        Problem {
            st: self.st,
            recs: self.recs,
            segs: segments(self.recs, single, seg_len),
            pscale: self.pscale.clone(),
            xs: self.xs.clone(),
            vs: self.vs.clone(),
            zs: self.zs.clone(),
            defect_weight,
            substeps: self.substeps,
            limit: BLOW_UP_LIMIT,
        }
    }
}

/// The coefficients as the stages leave them, with what the stages did.
pub(crate) struct Progress {
    pub coefs: Vec<f64>,
    pub iterations: usize,
    pub converged: bool,
    pub last_message: String,
    pub stages: Vec<serde_json::Value>,
}

impl Progress {
    /// Takes an LM stage's outcome on `pb` as the new coefficients.
    fn take(&mut self, pb: &Problem, out: &LmOutcome) {
        self.iterations += out.iterations;
        self.coefs = pb.coefs(&out.p);
        self.converged = out.converged;
        self.last_message = out.message.clone();
    }

    /// One multiple-shooting stage at continuity weight `wd` from the current coefficients;
    /// when a segment blows up at the start point the segments are halved (down to
    /// [`MIN_SEGMENT`] samples) and the stage tried again. Returns the segment length it ended
    /// with, which the later stages start from.
    pub fn shooting_stage(
        &mut self,
        setup: &Shooting,
        mut seg_len: usize,
        wd: f64,
        settings: &LmSettings,
    ) -> usize {
        let mut attempt = None;
        loop {
            let pb = setup.problem(false, seg_len, wd);
            let p0 = pb.initial(&self.coefs);
            debug_assert_eq!(p0.len(), pb.n_params());
            if let Some(out) = levenberg_marquardt(&pb, p0, settings) {
                attempt = Some((pb, out));
                break;
            }
            if seg_len <= MIN_SEGMENT {
                break;
            }
            seg_len = (seg_len / 2).max(MIN_SEGMENT);
        }
        match attempt {
            Some((pb, out)) => {
                self.take(&pb, &out);
                self.stages.push(json!({
                    "stage": "multiple shooting",
                    "segments": pb.segs.len(),
                    "segment_len": seg_len,
                    "defect_weight": wd,
                    "cost_start": out.cost0,
                    "cost_end": out.cost,
                    "defect_rms": out.defect_rms,
                    "iterations": out.iterations,
                    "message": out.message,
                }));
            }
            None => {
                self.stages.push(json!({
                    "stage": "multiple shooting",
                    "defect_weight": wd,
                    "message": "simulation of a segment blew up at the start; stage skipped",
                }));
            }
        }
        seg_len
    }

    /// The single-shooting polish (one segment per record) from the current coefficients,
    /// skipped when the free run blows up.
    pub fn polish(&mut self, setup: &Shooting, seg_len: usize, settings: &LmSettings) {
        let pb = setup.problem(true, seg_len, 0.0);
        let p0 = pb.initial(&self.coefs);
        match levenberg_marquardt(&pb, p0, settings) {
            Some(out) => {
                self.take(&pb, &out);
                self.stages.push(json!({
                    "stage": "single shooting polish",
                    "cost_start": out.cost0,
                    "cost_end": out.cost,
                    "iterations": out.iterations,
                    "message": out.message,
                }));
            }
            None => self.stages.push(json!({
                "stage": "single shooting polish",
                "message": "skipped: the free-run simulation blows up",
            })),
        }
    }
}

/// The segment length (samples) `opts` asks for: `segment_len` when set, else
/// `segment_periods` periods of the first record's dominant frequency (at least 4 samples;
/// 50 when it has none).
pub(crate) fn default_segment_len(recs: &[Prepared], opts: &RefineOptions) -> usize {
    match opts.segment_len {
        Some(l) => l,
        None => {
            let r0 = &recs[0];
            match dominant_frequency(&r0.xm[0], r0.dt) {
                Some(f) => ((opts.segment_periods / (f * r0.dt)).round() as usize).max(4),
                None => 50,
            }
        }
    }
}

/// Scales of the unknowns: each coefficient's start value; a state parameter that starts at 0
/// (a Bouc–Wen `b`) the largest parameter of its state, the scale of its effect; 1 otherwise.
pub(crate) fn parameter_scales(st: &Structure, coefs0: &[f64]) -> Vec<f64> {
    let pc = st.n_coefs();
    coefs0
        .iter()
        .enumerate()
        .map(|(k, c)| {
            if *c != 0.0 {
                return c.abs();
            }
            if k >= pc {
                let j = st.state_of(k - pc);
                let sib = (pc..coefs0.len())
                    .filter(|&q| st.state_of(q - pc) == j)
                    .map(|q| coefs0[q].abs())
                    .fold(0.0, f64::max);
                if sib > 0.0 {
                    return sib;
                }
            }
            1.0
        })
        .collect()
}

/// The shooting segments over every record: one per record when `single`, else consecutive
/// segments of `seg_len` samples sharing their end samples, a short last one merged into the
/// one before.
fn segments(recs: &[Prepared], single: bool, seg_len: usize) -> Vec<Segment> {
    let mut segs = Vec::new();
    for (ri, r) in recs.iter().enumerate() {
        let len = r.xm[0].len();
        if single {
            segs.push(Segment {
                rec: ri,
                k0: 0,
                k1: len - 1,
                linked: false,
            });
            continue;
        }
        let mut k0 = 0;
        while k0 < len - 1 {
            let mut k1 = (k0 + seg_len).min(len - 1);
            // Avoid a tiny last segment.
            if len - 1 - k1 < seg_len / 2 {
                k1 = len - 1;
            }
            segs.push(Segment {
                rec: ri,
                k0,
                k1,
                linked: k1 < len - 1,
            });
            k0 = k1;
        }
    }
    segs
}

/// `seg_len` halved (down to [`MIN_SEGMENT`] samples) while the start coefficients' mean
/// squared scaled error within segments exceeds 1, i.e. their segment predictions are off by
/// more than the signal RMS (an unstable or badly wrong start): multiple shooting only helps
/// with short segments.
pub(crate) fn shortened_segment_len(setup: &Shooting, coefs: &[f64], mut seg_len: usize) -> usize {
    let n = setup.st.n;
    let rows: f64 = setup.recs.iter().map(|r| (r.xm[0].len() * n) as f64).sum();
    while seg_len > MIN_SEGMENT {
        let pb = setup.problem(false, seg_len, 0.0);
        match pb.normal(&pb.initial(coefs)) {
            Some(nm) if 2.0 * nm.cost / rows <= 1.0 => break,
            _ => seg_len = (seg_len / 2).max(MIN_SEGMENT),
        }
    }
    seg_len
}
