"""Result objects of the Python API that carry a headline number and print as a short table."""

__all__ = ["Comparison"]


def _g(v):
    """A number with 4 significant digits (— for a missing one)."""
    return "—" if v is None else f"{v:.4g}"


class Comparison:
    """What ``Model.compare(records)`` measured: the model simulated under each record's
    measured input, from a state fitted to the record's start, scored against the record.

    ``r_mse`` is the headline: the mean over the records and DOFs of the R-MSE, the mean squared
    error over the measured variance (mean removed, so a DC level does not change it). It is the
    number ``tfs compare`` prints and the one ``tfs.diagnose`` reports for the same model and
    records as ``diagnose(...)["r_mse"]`` (its per-record ``records[i]["r_mse"]``).

    ``tfs.diagnose``'s ranked effects carry another quantity, ``r_mse_before`` and
    ``r_mse_after``: the prediction error of the model's structure *refitted* on part of the
    records and judged on the held-out rest (free run or short horizon), without and with the
    effect. It ranks effects; it is not the error of the model you pass, so it differs from
    ``r_mse``.

    Detail: ``per_dof`` (DOF -> mean R-MSE over the records), ``per_record`` (record -> DOF ->
    R-MSE), ``r_mse_mean_square`` (the paper's Appendix B ratio, over the mean square) and
    ``records`` (one dict per record as ``tfs compare --json`` gives its ``files``: ``path``,
    ``r_mse``, ``r_mse_mean_square``, per-DOF ``dofs`` with ``rms_error`` in the record's units
    and ``input_noise_spread`` and ``start_spread``, ``error_is_input_noise`` and
    ``run_diverges``). Iterating over a Comparison, or
    indexing it, gives those per-record dicts.
    """

    def __init__(self, records):
        self.records = list(records)

    @property
    def r_mse(self):
        """Mean R-MSE over the records and DOFs (mean squared error over the measured variance)."""
        vals = [d["r_mse"] for r in self.records for d in r["dofs"]]
        return sum(vals) / len(vals)

    @property
    def r_mse_mean_square(self):
        """Mean over the records and DOFs of the paper's Appendix B ratio (over the mean square)."""
        vals = [d["r_mse_mean_square"] for r in self.records for d in r["dofs"]]
        return sum(vals) / len(vals)

    @property
    def per_record(self):
        """``{record: {dof: R-MSE}}``."""
        return {r["path"]: {d["dof"]: d["r_mse"] for d in r["dofs"]} for r in self.records}

    @property
    def per_dof(self):
        """``{dof: mean R-MSE over the records}``."""
        sums = {}
        for r in self.records:
            for d in r["dofs"]:
                sums.setdefault(d["dof"], []).append(d["r_mse"])
        return {k: sum(v) / len(v) for k, v in sums.items()}

    def __iter__(self):
        return iter(self.records)

    def __len__(self):
        return len(self.records)

    def __getitem__(self, i):
        return self.records[i]

    def table(self):
        """The scores as a short text table: one row per record and DOF, then the mean."""
        rows = [("record", "dof", "R-MSE", "RMS error", "input-noise spread")]
        for r in self.records:
            name = str(r["path"]).replace("\\", "/").rsplit("/", 1)[-1]
            for d in r["dofs"]:
                rows.append(
                    (
                        name,
                        d["dof"],
                        _g(d["r_mse"]),
                        _g(d.get("rms_error")),
                        _g(d.get("input_noise_spread")),
                    )
                )
        widths = [max(len(row[k]) for row in rows) for k in range(len(rows[0]))]
        lines = ["  ".join(c.ljust(w) for c, w in zip(row, widths)).rstrip() for row in rows]
        lines.append(f"R-MSE (mean over records and DOFs): {_g(self.r_mse)}")
        noise = [r["path"] for r in self.records if r.get("error_is_input_noise")]
        if noise:
            lines.append(
                f"{len(noise)} record(s) whose error is mostly the measured input's own noise"
                " (it cannot rank models)"
            )
        apart = [r["path"] for r in self.records if r.get("run_diverges")]
        if apart:
            lines.append(
                f"{len(apart)} record(s) whose run parts from itself from a start the record"
                " cannot tell apart (it cannot rank models)"
            )
        return "\n".join(lines)

    def __str__(self):
        return self.table()

    def __repr__(self):
        return f"Comparison(r_mse={self.r_mse:.4g}, records={len(self.records)})\n{self.table()}"
