"""Snap classifier (paper III-B, Fig. 3a): P_snap(rho1, rho2), the probability that a release
from proximal preloads (rho1, rho2) exceeds 1 m/s (the protocol's attachment threshold, passed
in), fitted on the training-split
characterisation groups only. A logistic model on quadratic features of the standardised
preloads; session-grouped cross-validated AUC; the fraction of the explored box with P > 0.8;
the operating point. Saved as JSON; `load` gives the object the policy reward calls.
"""

from __future__ import annotations

import json

import numpy as np
from sklearn.linear_model import LogisticRegression

from ..sources import recordings
from .attachment import grouped_auc

P_HIGH = 0.8


def quad(r1, r2):
    """Quadratic features of standardised preloads (a ridge or valley in the box is allowed)."""
    return np.column_stack([r1, r2, r1 * r1, r1 * r2, r2 * r2])


class SnapModel:
    def __init__(self, d: dict):
        self.d = d

    def predict(self, rho1, rho2):
        """P_snap at preloads (ticks), any broadcastable shapes."""
        d = self.d
        r1, r2 = np.broadcast_arrays(np.asarray(rho1, float), np.asarray(rho2, float))
        z1, z2 = (r1.ravel() - d["mean"][0]) / d["scale"][0], (r2.ravel() - d["mean"][1]) / d["scale"][1]
        z = quad(z1, z2) @ np.array(d["coef"]) + d["intercept"]
        return (1 / (1 + np.exp(-z))).reshape(r1.shape)


def load(path) -> SnapModel:
    """The saved classifier (results/characterize/snap.json): load(path).predict(rho1, rho2)."""
    with open(path) as f:
        return SnapModel(json.load(f))


class _Quad:
    """sklearn-style model for grouped_auc: standardise, quadratic features, logistic."""

    def fit(self, X, y):
        self.m, self.s = X.mean(0), X.std(0) + 1e-12
        Z = (X - self.m) / self.s
        self.lr = LogisticRegression(C=1.0).fit(quad(Z[:, 0], Z[:, 1]), y)
        return self

    def predict_proba(self, X):
        Z = (X - self.m) / self.s
        return self.lr.predict_proba(quad(Z[:, 0], Z[:, 1]))


def fit(rows, attach_speed_mps: float, grid_n: int = 101) -> dict:
    r = [x for x in rows if np.isfinite(x["v_peak"])]
    X = np.array([[x["rho1"], x["rho2"]] for x in r], float)
    y = np.array([x["v_peak"] > attach_speed_mps for x in r], int)
    sess = np.array([x["session"] for x in r])
    out = dict(recordings=recordings([x["group_id"] for x in rows], [x["group_id"] for x in r],
                                     "no finite peak tip speed"),
               n=len(r), n_event=int(y.sum()), auc_grouped_cv=grouped_auc(X, y, sess, make=_Quad),
               trials=[dict(rho1=float(a), rho2=float(b), event=int(c)) for (a, b), c in zip(X, y)],
               box=[[float(X[:, 0].min()), float(X[:, 0].max())], [float(X[:, 1].min()), float(X[:, 1].max())]])
    if len(set(y)) < 2:
        # One class only (tiny budgets): a constant model, said so.
        p = float(y.mean()) if len(y) else 0.5
        out.update(mean=[0.0, 0.0], scale=[1.0, 1.0], coef=[0.0] * 5,
                   intercept=float(np.log((p + 1e-3) / (1 - p + 1e-3))), degenerate=True)
    else:
        m = _Quad().fit(X, y)
        out.update(mean=[float(v) for v in m.m], scale=[float(v) for v in m.s],
                   coef=[float(v) for v in m.lr.coef_[0]], intercept=float(m.lr.intercept_[0]), degenerate=False)
    model = SnapModel(out)
    g1 = np.linspace(*out["box"][0], grid_n)
    g2 = np.linspace(*out["box"][1], grid_n)
    P = model.predict(*np.meshgrid(g1, g2, indexing="ij"))
    high = P > P_HIGH
    out["fraction_box_p_gt_0p8"] = float(high.mean())
    # Operating point: the centroid of the P > 0.8 region, the preloads with the most margin on
    # every side (the argmax would sit on the box edge); the argmax when the region is empty.
    G1, G2 = np.meshgrid(g1, g2, indexing="ij")
    if high.any():
        op = [float(G1[high].mean()), float(G2[high].mean())]
    else:
        k = np.unravel_index(np.argmax(P), P.shape)
        op = [float(g1[k[0]]), float(g2[k[1]])]
    out["operating_point"] = op
    out["operating_point_p"] = float(model.predict(*op))
    out["grid"] = dict(rho1=g1.tolist(), rho2=g2.tolist(), p=P.round(5).tolist())
    return out
