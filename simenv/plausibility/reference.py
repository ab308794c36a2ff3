"""Scoring relative to real data: where a generated set falls in a real corpus.

The absolute thresholds of :mod:`simenv.plausibility.thresholds` are calibrated
on marker-based mocap, and real depth-camera skeletons fail them (748 of 749
real Kinect people are "implausible"), so on such data the absolute verdict
cannot tell a good generator from a bad one. Here every metric is instead
calibrated on a *reference*: the score records of real clips of the same
source (same sensor, skeleton and frame rate), and a generated clip is judged
by where its values fall in the reference's distribution.

Values
    Per person, the ``value`` of every available metric of the score record
    (:meth:`~simenv.plausibility.report.PlausibilityReport.to_records`;
    unavailable ones are skipped) and of every published metric
    (``published``, :mod:`simenv.plausibility.published`). Every metric is
    "larger is worse", so only the upper tail is judged: a generated clip
    smoother or better grounded than the real ones is not flagged.

Tail score of a value (:meth:`MetricCalibration.score`)
    From the sorted reference values ``r_1 <= ... <= r_n`` of a metric: below
    their 90th percentile ``u``, the mid-rank tail probability ``P(v) =
    (#{r_i > v} + #{r_i = v} / 2) / n``; above it, the exponential tail of
    peaks over a threshold, ``P(v) = P_u exp(-(v - u) / sigma)`` with ``P_u =
    #{r_i > u} / n`` and ``sigma`` the mean excess of the values above ``u``
    (a value beyond every real one still gets a finite, growing score; a
    metric whose real values never exceed ``u`` gets ``sigma`` =
    :data:`MIN_SIGMA`, so anything above them is far out). The score is
    ``S = -log10 P(v)`` and the percentile ``100 (1 - P(v))``. A metric with
    fewer than :data:`MIN_REFERENCE_PEOPLE` values is not calibrated.

Thresholds, calibrated out of sample (:func:`calibrate`)
    The reference people are split into :data:`FOLDS` folds by *group*
    (a subject, or by default the file: people of one group stay in one
    fold); each fold is scored against the other folds' calibration. The
    95th and 99th percentiles of these out-of-fold scores, per metric and
    for the *worst score* ``W = max_m S_m`` of each person (one number over
    all metrics), are the thresholds: about 5 % / 1 % of real clips of a new
    group of the same source exceed them, whatever the number of metrics.

Per clip (:meth:`Reference.judge`)
    Per metric the percentile and ``beyond_p95`` / ``beyond_p99`` (score above
    the metric's thresholds); the worst score and its metric; verdict
    ``"outside"`` when ``W`` exceeds its 99th-percentile threshold,
    ``"borderline"`` when it exceeds its 95th, else ``"inside"``.

Per set (:func:`compare`)
    Per metric and for ``W``: median percentile, share of clips beyond the
    p95 and p99 thresholds, and a p-value for the count ``k`` of ``m``
    clips beyond the p99 threshold under the hypothesis that the generated
    clips come from the reference's distribution. With ``e`` of the ``n``
    out-of-fold reference scores above the threshold, a new score exceeds
    it with probability ``Beta(e + 1, n - e)`` (exact when the threshold is
    the ``(n - e)``-th order statistic of continuous scores; the linear
    percentile lies between two of them), so ``k ~ BetaBinomial(m, e + 1,
    n - e)`` and ``p = P(K >= k)``, which accounts for the size of the
    reference as well as of the set. Verdict: ``"outside_reference"`` when
    ``p < alpha`` (0.01); ``"inside_reference"`` when not and the set is
    large enough that ``m`` of ``m`` beyond would have been significant;
    else ``"too_few_clips"``. The set's verdict is that of ``W``; the
    per-metric ones say which metrics move it.

Measured on the Kinect corpus (odd subjects as reference, even subjects
judged), with the numbers per dataset and corruption: ``docs/published_metrics.md``.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from html import escape
from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np
from scipy.stats import betabinom

from simenv.core.errors import ReferenceDataError

#: Fewest reference people a metric needs to be calibrated (with fewer, the
#: 99th percentile is the maximum of a handful of values).
MIN_REFERENCE_PEOPLE = 20
#: Percentiles of each metric's real values reported in the summary.
PERCENTILES: tuple[int, ...] = (50, 90, 95, 99)
#: Percentile of the real values above which the tail is exponential.
TAIL_PERCENTILE = 90.0
#: Scale (metric units) of the exponential tail of a metric whose real values
#: never exceed their 90th percentile: anything above them is far out.
MIN_SIGMA = 1e-9
#: Folds of the out-of-sample calibration of the thresholds.
FOLDS = 5
#: Significance level of the set verdicts.
ALPHA = 0.01
#: Relative tolerance on a generated clip's frame rate against the reference's.
FPS_TOLERANCE = 0.01

VERDICT_INSIDE = "inside_reference"
VERDICT_OUTSIDE = "outside_reference"
VERDICT_TOO_FEW = "too_few_clips"

#: Name of the reference-comparison page written next to the reports' index.
REFERENCE_PAGE = "reference.html"


def _label(rec: Mapping[str, Any]) -> str:
    label = f"{rec.get('file', '?')} person {rec.get('person', 0)}"
    return label + (f" clip {rec['clip']}" if "clip" in rec else "")


def _as_float(value: Any, rec: Mapping[str, Any], name: str) -> float:
    """A record's metric value as a float ("inf" from a diverged simulation is
    +inf); None or NaN for an available metric is an error."""
    if value == "inf":
        return math.inf
    try:
        out = math.nan if value is None else float(value)
    except (TypeError, ValueError):
        out = math.nan
    if math.isnan(out):
        raise ReferenceDataError(
            f"metric value is {value!r}; a metric marked available needs a number "
            f"({_label(rec)})", source=rec.get("file"), field=name)
    return out


def record_values(rec: Mapping[str, Any]) -> dict[str, float]:
    """Metric name -> value of one person's score record: every available
    metric (``passed`` not None) and every published metric with a value.

    Raises:
        ReferenceDataError: an available metric without a number (names the
            file and the metric).
    """
    out: dict[str, float] = {}
    for name, m in rec.get("metrics", {}).items():
        if m.get("passed") is not None:
            out[name] = _as_float(m.get("value"), rec, name)
    for name, m in rec.get("published", {}).items():
        if isinstance(m, Mapping) and "value" in m:
            out[name] = _as_float(m["value"], rec, name)
    return out


def exceedance_p_value(count: int, clips: int, above: int, reference: int) -> float:
    """``P(K >= count)`` for ``K ~ BetaBinomial(clips, above + 1, reference - above)``:
    the chance that ``count`` or more of ``clips`` scores from the reference's
    distribution exceed the reference's threshold with ``above`` of its
    ``reference`` scores above it (module docstring)."""
    if count <= 0:
        return 1.0
    return float(betabinom.sf(count - 1, clips, above + 1, reference - above))


def set_verdict(count: int, clips: int, above: int, reference: int,
                alpha: float = ALPHA) -> tuple[float, str]:
    """(p-value, verdict) of ``count`` of ``clips`` generated scores beyond a
    reference threshold (module docstring)."""
    p = exceedance_p_value(count, clips, above, reference)
    if p < alpha:
        return p, VERDICT_OUTSIDE
    powered = exceedance_p_value(clips, clips, above, reference) < alpha
    return p, VERDICT_INSIDE if powered else VERDICT_TOO_FEW


@dataclass(frozen=True)
class MetricCalibration:
    """One metric's reference distribution and tail model.

    Attributes:
        name: metric name; unit: its unit.
        values: (n,) float64 reference values, sorted ascending.
        u: the values' :data:`TAIL_PERCENTILE`-th percentile, where the
            exponential tail starts.
        tail_u: fraction of the values above ``u``.
        sigma: mean excess of the values above ``u`` (at least :data:`MIN_SIGMA`).
    """

    name: str
    unit: str
    values: np.ndarray
    u: float
    tail_u: float
    sigma: float

    @classmethod
    def fit(cls, name: str, unit: str, values: Sequence[float]) -> MetricCalibration:
        """Sort ``values`` and fit the exponential tail above their 90th percentile."""
        v = np.sort(np.asarray(values, dtype=np.float64))
        finite = v[np.isfinite(v)]
        u = float(np.percentile(finite, TAIL_PERCENTILE)) if len(finite) else 0.0
        excess = finite[finite > u] - u
        sigma = max(float(excess.mean()), MIN_SIGMA) if len(excess) else MIN_SIGMA
        return cls(name, unit, v, u, float(np.sum(v > u)) / len(v), sigma)

    @property
    def people(self) -> int:
        return int(len(self.values))

    def log_tail(self, value: float) -> float:
        """``log10 P(value)``: the (modelled) fraction of real values at or
        above ``value`` (module docstring)."""
        if value <= self.u or self.tail_u == 0.0:
            n = len(self.values)
            above = n - np.searchsorted(self.values, value, side="right")
            equal = n - above - np.searchsorted(self.values, value, side="left")
            p = (above + 0.5 * equal) / n
            if p > 0.0:
                return math.log10(p)
            # Beyond every real value of a metric whose values all sit at u.
            return math.log10(0.5 / n) - (value - self.values[-1]) / (MIN_SIGMA * math.log(10))
        if math.isinf(value):
            return -math.inf
        return math.log10(self.tail_u) - (value - self.u) / (self.sigma * math.log(10))

    def score(self, value: float) -> float:
        """Tail score ``S = -log10 P(value)`` (larger: further out)."""
        return -self.log_tail(value)

    def percentile(self, value: float) -> float:
        """``100 (1 - P(value))``."""
        return 100.0 * (1.0 - 10.0 ** self.log_tail(value))

    def summary(self) -> dict[str, float | int]:
        """The real values' count, percentiles and maximum."""
        out: dict[str, float | int] = {"people": self.people}
        with np.errstate(invalid="ignore"):
            out.update({f"p{q}": float(np.percentile(self.values, q)) for q in PERCENTILES})
        out["max"] = float(self.values[-1])
        return out


def _scores(metrics: Mapping[str, MetricCalibration], values: Mapping[str, float]
            ) -> dict[str, float]:
    return {n: metrics[n].score(v) for n, v in values.items() if n in metrics}


@dataclass(frozen=True)
class Threshold:
    """A score threshold calibrated out of fold.

    Attributes:
        oof: (n,) sorted out-of-fold scores of the reference people.
    """

    oof: np.ndarray

    def at(self, q: float) -> float:
        """The ``q``-th percentile of the out-of-fold scores."""
        return float(np.percentile(self.oof, q))

    def above(self, q: float) -> int:
        """How many out-of-fold scores exceed :meth:`at` ``q``."""
        t = self.at(q)
        return int(len(self.oof) - np.searchsorted(self.oof, t, side="right"))


@dataclass(frozen=True)
class Reference:
    """A real corpus calibrated for :meth:`judge` and :func:`compare`.

    Attributes:
        metrics: name -> :class:`MetricCalibration` on every reference
            person, calibrated metrics only.
        thresholds: name -> :class:`Threshold` of each metric's score, and
            ``"worst"`` -> that of the worst score ``W``.
        fps: frame rates of the reference clips.
        people: reference people (score records) used.
        files: reference files.
        skipped: ``[{file, error}]`` reference files that could not be scored.
        not_calibrated: metrics with values in fewer than
            :data:`MIN_REFERENCE_PEOPLE` reference people.
    """

    metrics: dict[str, MetricCalibration]
    thresholds: dict[str, Threshold]
    fps: tuple[float, ...]
    people: int
    files: tuple[str, ...]
    skipped: tuple[dict[str, str], ...] = ()
    not_calibrated: tuple[str, ...] = field(default=())

    def check_fps(self, rec: Mapping[str, Any]) -> None:
        """Raise unless ``rec``'s frame rate is one of the reference's.

        Raises:
            ReferenceDataError: names the file, field ``fps`` and both rates.
        """
        fps = float(rec.get("fps", math.nan))
        if not any(abs(fps - f) <= FPS_TOLERANCE * f for f in self.fps):
            rates = ", ".join(f"{f:g}" for f in self.fps)
            raise ReferenceDataError(
                f"generated clip at {fps:g} fps, the reference at {rates} fps: most metrics "
                "depend on the frame rate, so compare clips at the reference's rate "
                "(resample explicitly, simenv.Motion.resample)",
                source=rec.get("file"), field="fps")

    def judge(self, rec: Mapping[str, Any]) -> dict[str, Any]:
        """Where one generated person's score record falls in the reference.

        Returns:
            ``{percentiles: {metric: 0-100}, beyond_p95: [...], beyond_p99: [...],
            worst_score, worst_percentile, worst_metric, verdict ("inside" /
            "borderline" / "outside"), not_calibrated: [...]}`` (module docstring).

        Raises:
            ReferenceDataError: other frame rate than the reference, a
                non-numeric value of an available metric, or no calibrated
                metric in the record.
        """
        self.check_fps(rec)
        values = record_values(rec)
        scores = _scores(self.metrics, values)
        if not scores:
            raise ReferenceDataError(
                f"no metric of this clip is calibrated by the reference ({_label(rec)}; "
                f"reference metrics: {', '.join(self.metrics)})", source=rec.get("file"),
                field="metrics")
        beyond = {q: [n for n, s in scores.items() if s > self.thresholds[n].at(q)]
                  for q in (95, 99)}
        worst_metric = max(scores, key=lambda n: scores[n])
        worst = scores[worst_metric]
        w = self.thresholds["worst"]
        verdict = ("outside" if worst > w.at(99) else
                   "borderline" if worst > w.at(95) else "inside")
        return {"percentiles": {n: round(self.metrics[n].percentile(values[n]), 3)
                                for n in scores},
                "beyond_p95": beyond[95], "beyond_p99": beyond[99],
                "worst_score": round(worst, 4),
                "worst_percentile": round(self.metrics[worst_metric].percentile(
                    values[worst_metric]), 4),
                "worst_metric": worst_metric, "verdict": verdict,
                "not_calibrated": sorted(set(values) - set(self.metrics))}


def _people(records: Iterable[Mapping[str, Any]]
            ) -> tuple[list[Mapping[str, Any]], list[dict[str, str]]]:
    ok, errors = [], []
    for rec in records:
        if "error" in rec:
            errors.append({"file": str(rec.get("file")), "error": str(rec["error"])})
        else:
            ok.append(rec)
    return ok, errors


def _fit_all(units: Mapping[str, str], values: Sequence[Mapping[str, float]], min_people: int
             ) -> dict[str, MetricCalibration]:
    out = {}
    for name, unit in units.items():
        column = [v[name] for v in values if name in v]
        if len(column) >= min_people:
            out[name] = MetricCalibration.fit(name, unit, column)
    return out


def _out_of_fold(units: Mapping[str, str], values: Sequence[Mapping[str, float]],
                 groups: Sequence[str], min_people: int) -> list[dict[str, float]]:
    """Each person's scores against the calibration of the folds without
    their group (module docstring)."""
    order = list(dict.fromkeys(groups))
    folds = min(FOLDS, len(order))
    fold_of = {g: i % folds for i, g in enumerate(order)}
    fold = np.array([fold_of[g] for g in groups])
    out: list[dict[str, float]] = [{} for _ in values]
    for f in range(folds):
        train = [v for v, k in zip(values, fold, strict=True) if k != f]
        metrics = _fit_all(units, train, min_people)
        for i in np.flatnonzero(fold == f):
            out[i] = _scores(metrics, values[i])
    return out


def calibrate(records: Iterable[Mapping[str, Any]], *,
              groups: Sequence[str] | None = None,
              min_people: int = MIN_REFERENCE_PEOPLE) -> Reference:
    """Calibrate every metric on the score records of a real corpus.

    Args:
        records: score records of the real clips (``simenv score --json``
            lines, :func:`simenv.plausibility.batch.score_batch`); error records are
            skipped and listed.
        groups: one group key per record (e.g. the subject), error records
            included; people of one group share a fold of the out-of-sample
            calibration. Default: the record's file.
        min_people: fewest values a metric needs to be calibrated.

    Raises:
        ReferenceDataError: no scored person at all (empty reference), no
            metric with ``min_people`` values, fewer than two groups, a
            ``groups`` of another length, or a non-numeric value of an
            available metric (names the file and the metric).
    """
    records = list(records)
    if groups is not None and len(groups) != len(records):
        raise ReferenceDataError(f"{len(groups)} groups for {len(records)} records",
                                 field="groups")
    keys = [str(rec.get("file")) for rec in records] if groups is None else list(groups)
    people, errors = _people(records)
    if not people:
        why = f"; {len(errors)} file(s) could not be scored" if errors else ""
        raise ReferenceDataError(f"the reference has no scored clip{why}: give real clips of "
                                 "the same source as the generated ones", field="reference")
    groups = [k for k, rec in zip(keys, records, strict=True) if "error" not in rec]
    if len(set(groups)) < 2:
        raise ReferenceDataError("the reference needs at least two files (groups) to calibrate "
                                 "its thresholds out of sample", field="reference")
    values = [record_values(rec) for rec in people]
    units: dict[str, str] = {}
    for rec in people:
        for section in ("metrics", "published"):
            for n, m in rec.get(section, {}).items():
                if isinstance(m, Mapping) and "unit" in m:
                    units.setdefault(n, m["unit"])
    metrics = _fit_all(units, values, min_people)
    if not metrics:
        raise ReferenceDataError(
            f"no metric has values in at least {min_people} reference people (the reference "
            f"has {len(people)}); give a larger real corpus", field="reference")
    oof = _out_of_fold({n: units[n] for n in metrics}, values, groups, min_people)
    thresholds = {n: Threshold(np.sort([s[n] for s in oof if n in s])) for n in metrics}
    thresholds = {n: t for n, t in thresholds.items() if len(t.oof)}
    metrics = {n: m for n, m in metrics.items() if n in thresholds}
    worst = [max((v for n, v in s.items() if n in metrics), default=-math.inf) for s in oof]
    thresholds["worst"] = Threshold(np.sort([w for w in worst if w > -math.inf]))
    fps = tuple(sorted({round(float(rec["fps"]), 6) for rec in people}))
    files = tuple(dict.fromkeys(str(rec.get("file")) for rec in people))
    return Reference(metrics=metrics, thresholds=thresholds, fps=fps, people=len(people),
                     files=files, skipped=tuple(errors),
                     not_calibrated=tuple(sorted(set(units) - set(metrics))))


def compare(reference: Reference, records: Iterable[Mapping[str, Any]],
            alpha: float = ALPHA) -> dict[str, Any]:
    """Where a generated set falls in ``reference``, per metric and overall.

    Args:
        reference: from :func:`calibrate`.
        records: the generated clips' score records (judged again: an
            earlier ``reference`` entry may come from another reference);
            error records are listed.
        alpha: significance level of the verdicts.

    Returns:
        JSON-ready ``{verdict, overall, metrics, reference, generated}``
        (module docstring): ``overall`` for the worst score ``W``,
        ``metrics`` per calibrated metric (the real values' percentiles; the
        generated median percentile, shares beyond the p95 / p99
        thresholds, p-value, verdict).

    Raises:
        ReferenceDataError: no generated person was scored, or one cannot be
            judged (other frame rate, non-numeric value).
    """
    people, errors = _people(records)
    if not people:
        raise ReferenceDataError("no generated clip was scored: nothing to compare with the "
                                 "reference", field="generated")
    judged = [reference.judge(rec) for rec in people]

    def tally(name: str, key: str, present: list[dict[str, Any]]) -> dict[str, Any]:
        t = reference.thresholds[key]
        k95 = sum(name in j["beyond_p95"] for j in present) if key != "worst" else \
            sum(j["verdict"] != "inside" for j in present)
        k99 = sum(name in j["beyond_p99"] for j in present) if key != "worst" else \
            sum(j["verdict"] == "outside" for j in present)
        m = len(present)
        p, verdict = set_verdict(k99, m, t.above(99), len(t.oof), alpha)
        return {"people": m, "share_beyond_p95": k95 / m, "share_beyond_p99": k99 / m,
                "expected_share_beyond_p99": (t.above(99) + 1) / (len(t.oof) + 1),
                "p_value": p, "verdict": verdict}

    metrics: dict[str, Any] = {}
    for name, cal in reference.metrics.items():
        entry: dict[str, Any] = {"unit": cal.unit, "reference": cal.summary()}
        present = [j for j in judged if name in j["percentiles"]]
        if present:
            entry["generated"] = {
                "median_percentile": float(np.median([j["percentiles"][name]
                                                      for j in present])),
                **tally(name, name, present)}
        metrics[name] = entry
    overall = {"statistic": "worst_score",
               "median_worst_percentile": float(np.median([j["worst_percentile"]
                                                           for j in judged])),
               **tally("worst", "worst", judged), "alpha": alpha}
    return {
        "verdict": overall["verdict"],
        "overall": overall,
        "metrics": metrics,
        "reference": {"people": reference.people, "files": len(reference.files),
                      "fps": list(reference.fps), "skipped": list(reference.skipped),
                      "not_calibrated": list(reference.not_calibrated)},
        "generated": {"people": len(people), "errors": errors,
                      "outside": sum(j["verdict"] == "outside" for j in judged),
                      "borderline": sum(j["verdict"] == "borderline" for j in judged)},
    }


def read_records(path: str | os.PathLike[str]) -> list[dict[str, Any]]:
    """Score records of a JSON-lines results file (``simenv score --out``).

    Raises:
        ReferenceDataError: the file is missing, or a line is not a JSON
            object (names the file and the line).
    """
    path = Path(path)
    if not path.is_file():
        raise ReferenceDataError("no such results file", source=path)
    out = []
    with path.open(encoding="utf-8") as fh:
        for i, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                rec = json.loads(line)
            except json.JSONDecodeError as exc:
                raise ReferenceDataError(f"not a JSON line: {exc.msg}", source=path,
                                         line=i) from exc
            if not isinstance(rec, dict) or "file" not in rec:
                raise ReferenceDataError("expected a score record (a JSON object with 'file')",
                                         source=path, line=i)
            out.append(rec)
    return out


def _cell(x: float, digits: int = 4) -> str:
    return "&ndash;" if x is None or math.isnan(x) else f"{x:.{digits}g}"


def write_reference_page(summary: Mapping[str, Any],
                         records: Sequence[Mapping[str, Any]],
                         out_dir: str | os.PathLike[str]) -> Path:
    """Write ``out_dir/reference.html``: the set verdict, a per-metric table
    (reference percentiles, generated median percentile, shares beyond the
    reference's p95 / p99, p-value, verdict) and one row per generated clip
    (worst percentile and metric, verdict, link to its report page, relative).

    Args:
        summary: from :func:`compare`.
        records: the generated records (judged: with a ``reference`` entry).
        out_dir: the reports' folder.
    """
    from simenv.plausibility.html_report import html_page  # the scorer's page: MuJoCo

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    o = summary["overall"]
    head = (f"<h1>Generated set against a real reference</h1>"
            f"<p>Verdict: <b>{escape(summary['verdict'])}</b>. "
            f"{summary['generated']['people']} generated people against "
            f"{summary['reference']['people']} real ones "
            f"({summary['reference']['files']} files, "
            f"{', '.join(f'{f:g}' for f in summary['reference']['fps'])} fps). "
            f"Worst score over the metrics: {100 * o['share_beyond_p99']:.1f} % of the "
            f"generated clips beyond the reference's 99th percentile (expected for real clips: "
            f"{100 * o['expected_share_beyond_p99']:.1f} %), "
            f"{100 * o['share_beyond_p95']:.1f} % beyond its 95th; p = {o['p_value']:.3g}.</p>")
    rows = []
    for name, m in summary["metrics"].items():
        r, g = m["reference"], m.get("generated")
        gen = ("<td colspan='5'>not in the generated set</td>" if g is None else
               f"<td class='num'>{g['median_percentile']:.1f}</td>"
               f"<td class='num'>{100 * g['share_beyond_p95']:.1f} %</td>"
               f"<td class='num'>{100 * g['share_beyond_p99']:.1f} %</td>"
               f"<td class='num'>{g['p_value']:.3g}</td><td>{escape(g['verdict'])}</td>")
        rows.append(f"<tr><td>{escape(name)}</td><td>{escape(m['unit'])}</td>"
                    + "".join(f"<td class='num'>{_cell(r[f'p{q}'])}</td>" for q in PERCENTILES)
                    + gen + "</tr>")
    table = ("<h2>Per metric</h2><table><tr><th>metric</th><th>unit</th>"
             + "".join(f"<th>real p{q}</th>" for q in PERCENTILES)
             + "<th>generated median percentile</th><th>beyond real p95</th>"
             "<th>beyond real p99</th><th>p-value</th><th>verdict</th></tr>"
             + "".join(rows) + "</table>")
    clips = []
    for rec in records:
        if "reference" not in rec:
            continue
        j = rec["reference"]
        name = escape(_label(rec))
        page = rec.get("report")
        if page:
            target = Path(page) if Path(page).is_absolute() else out / page
            href = quote(Path(os.path.relpath(target, out)).as_posix())
            name = f"<a href='{escape(href)}'>{name}</a>"
        clips.append(f"<tr><td>{name}</td><td class='num'>{j['worst_percentile']:.1f}</td>"
                     f"<td>{escape(j['worst_metric'])}</td><td>{escape(j['verdict'])}</td>"
                     f"<td class='small'>{escape(', '.join(j['beyond_p99']))}</td></tr>")
    clip_table = ("<h2>Per generated clip</h2><table><tr><th>clip</th><th>worst percentile</th>"
                  "<th>worst metric</th><th>verdict</th><th>beyond real p99</th></tr>"
                  + "".join(clips) + "</table>")
    path = out / REFERENCE_PAGE
    path.write_text(html_page("simenv: generated vs real reference",
                              head + table + clip_table), encoding="utf-8")
    return path


__all__ = [
    "ALPHA",
    "FOLDS",
    "FPS_TOLERANCE",
    "MIN_REFERENCE_PEOPLE",
    "MIN_SIGMA",
    "PERCENTILES",
    "REFERENCE_PAGE",
    "TAIL_PERCENTILE",
    "VERDICT_INSIDE",
    "VERDICT_OUTSIDE",
    "VERDICT_TOO_FEW",
    "MetricCalibration",
    "Reference",
    "Threshold",
    "calibrate",
    "compare",
    "exceedance_p_value",
    "read_records",
    "record_values",
    "set_verdict",
    "write_reference_page",
]
