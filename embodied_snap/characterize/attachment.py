"""Attachment (paper III-B, Fig. 2c): a descriptive speed/cup-tilt logistic model with
session-grouped cross-validated AUC; attachments below 1 m/s; the attach fraction among trials
arriving within 150 mm laterally and above 1 m/s (the protocol's attachment threshold, passed in)."""

from __future__ import annotations

import numpy as np
from sklearn.linear_model import LogisticRegression
from sklearn.metrics import roc_auc_score
from sklearn.model_selection import GroupKFold
from sklearn.pipeline import make_pipeline
from sklearn.preprocessing import StandardScaler
from statsmodels.stats.proportion import proportion_confint

from ..rawformat import RecordingError
from ..sources import recordings

LATERAL_M = 0.150


def model():
    return make_pipeline(StandardScaler(), LogisticRegression())


def grouped_auc(X, y, groups, make=model, n_splits=5) -> float:
    """AUC of out-of-fold predictions, folds by group (session), so that one session's
    stiffness and calibration never sit on both sides. NaN where a class is missing."""
    k = min(n_splits, len(set(groups)))
    if k < 2 or len(set(y)) < 2:
        return float("nan")
    p = np.full(len(y), np.nan)
    for tr, te in GroupKFold(n_splits=k).split(X, y, groups):
        if len(set(y[tr])) < 2:
            p[te] = y[tr].mean()
            continue
        p[te] = make().fit(X[tr], y[tr]).predict_proba(X[te])[:, 1]
    return float(roc_auc_score(y, p))


def fit(rows, attach_speed_mps: float) -> dict:
    # Every trial the gate passed is measurable; one that is not stops the fit, never drops out of it.
    for x in rows:
        if not (np.isfinite(x["v_peak"]) and np.isfinite(x["tilt_deg"])):
            raise RecordingError(f"groups/{x['group_id']}/mocap.parquet", x["group_id"],
                                 "no peak speed or cup tilt to fit", "attachment trial measurable")
    r = rows
    X = np.array([[x["v_peak"], x["tilt_deg"]] for x in r])
    y = np.array([bool(x["attached"]) for x in r], int)
    sess = np.array([x["session"] for x in r])
    out = dict(recordings=recordings([x["group_id"] for x in r], [x["group_id"] for x in r]),
               n=len(r), n_attached=int(y.sum()), auc_grouped_cv=grouped_auc(X, y, sess),
               trials=[dict(v=float(a), tilt=float(b), attached=int(c)) for (a, b), c in zip(X, y)])
    if len(set(y)) == 2:
        m = model().fit(X, y)
        sc, lr = m[0], m[1]
        # The full-data fit, in raw units, for the figure's contours: logit = b0 + b . x
        out["coef"] = [float(c) for c in lr.coef_[0] / sc.scale_]
        out["intercept"] = float(lr.intercept_[0] - (lr.coef_[0] * sc.mean_ / sc.scale_).sum())
    out["attached_below_1mps"] = int(((X[:, 0] < attach_speed_mps) & (y == 1)).sum()) if len(r) else 0
    lat = np.array([x["lateral_m"] for x in r])
    near = (lat <= LATERAL_M) & (X[:, 0] > attach_speed_mps) if len(r) else np.zeros(0, bool)
    k, n = int(y[near].sum()), int(near.sum())
    out.update(near_fast_n=n, near_fast_attached=k, near_fast_fraction=k / n if n else float("nan"),
               near_fast_ci95=[float(x) for x in proportion_confint(k, n, method="wilson")] if n else [np.nan] * 2)
    return out


def probability(fit_out, v, tilt):
    """The full-data model's P(attach) at speed v (m/s) and tilt (deg)."""
    z = fit_out["intercept"] + fit_out["coef"][0] * np.asarray(v) + fit_out["coef"][1] * np.asarray(tilt)
    return 1 / (1 + np.exp(-z))
