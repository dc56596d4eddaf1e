//! `tfs basin` and `tfs med` on a chain model (two or more DOFs): the basins of its stable states
//! on the paper's slice `x_i(0) = x_i(S1) + Δx`, `x_i'(0) = v0`, and the minimum-energy deployment
//! between two of them.

use std::path::Path;

use anyhow::{Result, anyhow};
use serde_json::{Value, json};
use tfs::basin::{BasinConfig, BasinMap, ChainMed, Slice, basin_chain, med_chain};
use tfs::chain::{CellStates, ChainModel, model_chain};
use tfs::library::{CompiledModel, Model};

use super::parse_range;

/// Δx range of the slice when `--x` is not given.
pub const DEFAULT_DX: &str = "-1.2:1";
/// Range of cell heights searched for equilibria when `--search` is not given.
pub const DEFAULT_SEARCH: &str = "-0.05:2.2";

/// A chain model's basin map on the paper's slice through its first stable state.
pub struct ChainMap {
    /// The cells and wells.
    pub chain: ChainModel,
    /// The compiled model.
    pub system: CompiledModel,
    /// The slice the map lies on.
    pub slice: Slice,
    /// The grid.
    pub cfg: BasinConfig,
    /// The map.
    pub map: BasinMap,
}

/// Reads the chain's cells on `search` (text `A:B`, default [`DEFAULT_SEARCH`]) and maps the
/// basins on the grid `cfg` (its x range is Δx).
pub fn chain_map(
    label: &str,
    model: &Model,
    search: Option<&str>,
    cfg: BasinConfig,
) -> Result<ChainMap> {
    let search = parse_range(search.unwrap_or(DEFAULT_SEARCH), "--search")?;
    let chain = model_chain(label, model, search)?;
    let system = model.compile()?;
    let slice = Slice::paper(&chain.wells.stable()[0]);
    let map = basin_chain(&system, &chain.wells, &slice, &cfg, None).map_err(|e| {
        anyhow!(
            "{label}: basin map of the chain on --x (Δx) {:?}, --v {:?}: {e}",
            cfg.x_range,
            cfg.v_range
        )
    })?;
    Ok(ChainMap {
        chain,
        system,
        slice,
        cfg,
        map,
    })
}

/// Heights with four decimals, comma-separated (`—` for none).
fn list(v: &[f64]) -> String {
    if v.is_empty() {
        return "—".into();
    }
    v.iter()
        .map(|x| format!("{x:.4}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A chain state `(x1, x2, …)` with four decimals.
fn state(x: &[f64]) -> String {
    format!("({})", list(x))
}

/// A cell's [`tfs::chain::FoldedBalance`] as JSON (`null` without one).
pub fn folded_json(s: &CellStates) -> Value {
    s.folded.as_ref().map_or(
        Value::Null,
        |f| json!({"h": 0.0, "term": f.term, "coef": f.coef, "interval": f.interval}),
    )
}

/// The cells, states and shares as JSON.
pub fn chain_json(c: &ChainMap) -> Value {
    json!({
        "cells": c.chain.cells.iter().map(|s| json!({"stable": s.stable, "unstable": s.unstable, "folded_undecided": folded_json(s), "rests_on_stop": s.on_stop})).collect::<Vec<_>>(),
        "masses": c.chain.masses,
        "stable": c.chain.wells.stable(),
        "slice": "x_i(0) = x_i(S1) + dx, v_i(0) = v0",
        "dx_range": [c.cfg.x_range.0, c.cfg.x_range.1],
        "v_range": [c.cfg.v_range.0, c.cfg.v_range.1],
        "shares": c.map.shares,
        "unsettled": c.map.unsettled_count,
        "diverged": c.map.diverged_count,
        "integrated": c.map.integrated,
        "seconds": c.map.seconds,
    })
}

/// The cells' equilibria as sentences; for a model that is not tied, what each cell's law
/// took from the next cell's terms in its equation and how its stable heights depend on where
/// the next cell rests.
pub fn print_cells(cells: &[CellStates], tied: bool) {
    for (i, s) in cells.iter().enumerate() {
        let kind = match s.stable.len() {
            1 => "monostable".to_string(),
            2 => "bistable".to_string(),
            n => format!("{n} stable heights"),
        };
        println!(
            "cell {}: {kind}; stable h = {}; unstable h = {}",
            i + 1,
            list(&s.stable),
            list(&s.unstable)
        );
        if let Some(f) = &s.folded {
            println!(
                "  h = 0 (folded flat) is a balance of every law this library can form, and the model is stable there only by the sign of {}'s coefficient, {} in [{}, {}], which the records do not decide: not counted as a stable state (the model's simulations can still settle there; `tfs refit --add stop@x{}` fits the folded stop a real cell meets there)",
                f.term,
                super::trace_view::sig(f.coef),
                super::trace_view::sig(f.interval[0]),
                super::trace_view::sig(f.interval[1]),
                i + 1
            );
        }
        if !s.on_stop.is_empty() {
            println!(
                "  it also rests pressed into its stop at h = {}: not counted as a stable state (a stop a little past the fold holds the folded cell where the law's balance at the fold is unstable)",
                list(&s.on_stop)
            );
        }
        if tied || s.by_next.is_empty() {
            continue;
        }
        let at: Vec<String> = s
            .by_next
            .iter()
            .map(|(z, h)| format!("at {z:.4}: h = {}", list(h)))
            .collect();
        println!(
            "  with cell {}'s terms in x{}'' taken where cell {} rests ({:.4} per unit mass; the fit was not tied, so the data fix only the sum of cell {}'s terms and these); with cell {} {}",
            i + 2,
            i + 1,
            i + 2,
            s.coupling_at_rest,
            i + 1,
            i + 2,
            at.join("; ")
        );
        if s.by_next.iter().any(|(_, h)| h.len() != s.stable.len()) {
            println!(
                "  warning: cell {}'s kind depends on where cell {} rests: this untied fit cannot separate the two cells' laws; fit with ties (the default for a chain)",
                i + 1,
                i + 2
            );
        }
    }
}

/// The cells' equilibria and the chain's stable states, as sentences.
pub fn print_states(c: &ChainMap) {
    print_cells(&c.chain.cells, c.chain.tied);
    for (k, s) in c.chain.wells.stable().iter().enumerate() {
        println!("S{}: x = {}", k + 1, state(s));
    }
}

/// Prints a chain's basin map (`tfs basin` on a chain model) and writes its figure to `out`.
pub fn report_basin(c: &ChainMap, title: &str, out: Option<&Path>, json_out: bool) -> Result<()> {
    let mut v = chain_json(c);
    let mut files = Vec::new();
    if let Some(path) = out {
        let names: Vec<String> = c
            .chain
            .wells
            .stable()
            .iter()
            .enumerate()
            .map(|(k, s)| {
                let xs: Vec<String> = s.iter().map(|x| format!("{x:.3}")).collect();
                format!("S{} ({})", k + 1, xs.join(", "))
            })
            .collect();
        files = super::plots::basin_figure_on(
            &c.map,
            title,
            (
                "Δx, shift of every displacement from S1 (record's length unit)",
                "v0, initial velocity of every mass (record's length unit / s)",
            ),
            &names,
            None,
            path,
        )?;
        v["files"] = json!(files);
    }
    if json_out {
        return super::print_json(&v);
    }
    print_states(c);
    println!(
        "slice: every displacement shifted by Δx from S1, every mass started at velocity v0 (Δx {}:{}, v0 {}:{})",
        c.cfg.x_range.0, c.cfg.x_range.1, c.cfg.v_range.0, c.cfg.v_range.1
    );
    for (k, s) in c.map.shares.iter().enumerate() {
        println!("basin of S{}: {:.2} %", k + 1, 100.0 * s);
    }
    println!(
        "{} × {} starts, {} integrated ({:.1} %), the rest labelled from agreeing neighbours; {:.2} s",
        c.cfg.nx,
        c.cfg.ny,
        c.map.integrated,
        100.0 * c.map.integrated as f64 / (c.cfg.nx * c.cfg.ny) as f64,
        c.map.seconds
    );
    if c.map.unsettled_count + c.map.diverged_count > 0 {
        println!(
            "unsettled: {}, diverged: {} (a start that falls through a cell's folded state diverges when the model has no stop there: `tfs diagnose` finds it, `tfs refit --add stop@x1 --add stop@x2` adds it)",
            c.map.unsettled_count, c.map.diverged_count
        );
    }
    if !files.is_empty() {
        println!("written: {}", files.join(", "));
    }
    Ok(())
}

/// The minimum-energy deployment from stable state `from` to `to` (1-based) of a chain's map.
pub fn med(c: &ChainMap, from: usize, to: usize) -> Result<ChainMed> {
    let n = c.chain.wells.stable().len();
    if n < 2 {
        anyhow::bail!("the chain has {n} stable state(s) on the searched heights; MED needs two");
    }
    if from == 0 || to == 0 || from > n || to > n || from == to {
        anyhow::bail!("--from {from} --to {to}: give two different states between 1 and {n}");
    }
    Ok(med_chain(
        &c.system,
        &c.chain.wells,
        &c.slice,
        &c.map,
        &c.cfg,
        from - 1,
        to - 1,
    )?)
}

/// Prints a chain's MED (`tfs med` on a chain model).
pub fn report_med(
    c: &ChainMap,
    m: &ChainMed,
    from: usize,
    to: usize,
    json_out: bool,
) -> Result<()> {
    let s = c.chain.wells.stable();
    if json_out {
        let mut v = chain_json(c);
        v["med"] = json!({"from": s[from - 1], "to": s[to - 1], "dx": m.c0, "v0": m.c1,
            "x0": m.x, "v": m.v, "energy": m.energy, "quasi_static_barrier": m.quasi_static_barrier});
        return super::print_json(&v);
    }
    print_states(c);
    println!(
        "MED from S{from} {} to S{to} {}: E_in = {:.5} at Δx = {:.4}, v0 = {:.4} (x0 = {})",
        state(&s[from - 1]),
        state(&s[to - 1]),
        m.energy,
        m.c0,
        m.c1,
        state(&m.x)
    );
    if let Some(b) = m.quasi_static_barrier {
        println!("  quasi-static barrier (lowest saddle above S{from}): {b:.5}");
    }
    Ok(())
}
