"""Compare the CasADi contact steps with the independent NumPy oracle.

``symcushion.contact.contact_step(method)`` (method 'paper', 'robust',
'implicit') is a casadi.Function with inputs P0, Dp, n, l, mu, u0 and outputs
delta, P, k, contact (docs/contact-spec.md).  ``tests/oracle_contact.py`` is
a scalar NumPy transcription of the same spec, written without reading the
package.  Each method is evaluated, batched with ``f.map(N)``, on
``CASES_PER_KIND`` cases of each kind of ``oracle_contact.random_cases``
(spd, nonsym, singular, plane), and must agree with the oracle to ``TOL``.

Error scales (per case; |.| is the Euclidean norm, |Dp| the spectral norm):

* displacement scale  S_d = max(|l|, |delta_o|, |delta_f|, terms), where the
  terms are the pieces delta is summed from in the oracle: |k1 s|, |k2 l_tau|,
  |k3| (e is a unit vector) for paper/robust, |g| for implicit; plus |u0|
  when either side lifts off (then delta = -u0).
* force scale  S_P = max(|P0|, |P_o|, |P_f|, |Dp| S_d).  This is the scale
  max(|P0|, |P|, |Dp| |l|) of the brief with |l| replaced by S_d >= |l|:
  P = P0 + Dp delta, so an agreement of delta to TOL S_d can only promise
  |Dp| TOL S_d in P.
* k: paper/robust compare what k contributes to delta: |dk1| |s| / S_d,
  |dk2| |l_tau| / S_d (|dk2| itself when l_tau = 0), |dk3| / S_d; implicit
  |dg| / S_d.
* the contact flag must agree exactly, and every output must be finite.

A case fails when max(err_delta, err_P, err_k) > TOL or the flags differ.  A
failing case is excused -- counted per category and printed, never
silently -- only in one of these categories (checked in this order):

1. ``roundoff``: the oracle's own output moves by at least
   err/SPREAD_FACTOR when the inputs are perturbed norm-wise by ROUND_ETAS
   (0.5 and 4.5 ulp; see ``_perturb``), whatever branches it then takes;
   the flags must agree, or the oracle's own flag must flip under such a
   perturbation.  The two implementations round differently and the case's
   conditioning amplifies it past TOL (sqrt(eps) at a double root of (1.11)
   or of (1.15) at mu = 0; eps cond(Dp) for near-singular Dp; a decision
   such as C0 > 0 taken on a C0 that is pure round-off).
2. ``threshold``: perturbing the inputs by at most THRESH_ETA changes the
   oracle's branch path, and the Function's output agrees to
   max(TOL, SPREAD_FACTOR spread) with the oracle evaluated on the
   *unperturbed* inputs with the decisions of that other path forced: the
   Function took the other side of a branch whose test is within round-off
   of its threshold.
3. ``at-threshold``: a perturbation of 0.5-4.5 ulp already changes the
   oracle's branch path (a test decided by round-off, e.g. C = +-1e-16 |P|^2
   or the sign of a pure-round-off vector), but neither side reproduces the
   Function, because the values after the branch are round-off too.

Everything else is a ``disagree`` case: the test fails and prints it.  The
number of excused cases is capped per method (MAX_EXCUSED_FRACTION, set at
about 1.5 times the measured rate).  Run ``python tests/test_contact_oracle.py``
for the full report.
"""

from __future__ import annotations

import sys
import time

import numpy as np
import pytest

import oracle_contact as oc  # on sys.path: pytest prepends this folder (conftest.py)

TOL = 1e-12
CASES_PER_KIND = 3000          # x 4 kinds = 12,000 cases per method
SEED = 20240611
THRESH_ETA = (1e-15, 1e-14, 1e-13, 1e-12)   # relative input perturbations
THRESH_DRAWS = 6                           # random draws per size
ROUND_ETAS = (1e-16, 1e-15)    # 'round-off' perturbations (0.5 and 4.5 ulp)
ROUND_DRAWS = 24                # random draws per size
MAX_DISAGREE_CLASSIFIED = 100   # classify at most this many disagreements
EXTENDED_DRAWS = 150            # extra draws per size while disagreements are few
EXTENDED_WHILE = 10             # ... i.e. fewer than this many so far
SPREAD_FACTOR = 10.0
# excused cases must stay rare; measured (seed SEED): paper 8.5 %, robust
# 2.0 %, implicit 1.1 % -- the printed step is ill-conditioned by design
MAX_EXCUSED_FRACTION = {"paper": 0.13, "robust": 0.03, "implicit": 0.02}
EXCUSED = ("roundoff", "threshold", "at-threshold")

METHODS = ("paper", "robust", "implicit")
#: Methods compared output by output with their transcription. The implicit
#: step's spec is a rule (every solution, the least slip), checked against a
#: brute-force search with tolerances set by conditioning rather than by a
#: line-by-line transcription: tests/test_contact_exact.py.
COMPARED = ("paper", "robust")
ORACLES = {"paper": oc.paper_step, "robust": oc.robust_step,
           "implicit": oc.implicit_step}


# ---------------------------------------------------------------------------
# cases and evaluation
# ---------------------------------------------------------------------------

def make_cases(per_kind=CASES_PER_KIND, seed=SEED):
    rng = np.random.default_rng(seed)
    parts = [oc.random_cases(rng, per_kind, kind) for kind in oc.KINDS]
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}


def eval_function(f, cases):
    """Evaluate the casadi.Function on all cases at once with f.map(N)."""
    N = len(cases["mu"])
    F = f.map(N)
    args = {"P0": cases["P0"].T, "Dp": cases["Dp"].transpose(1, 0, 2).reshape(3, 3 * N),
            "n": cases["n"].T, "l": cases["l"].T, "mu": cases["mu"][None, :],
            "u0": cases["u0"].T}
    res = F(**args)
    return (np.array(res["delta"]).T, np.array(res["P"]).T, np.array(res["k"]).T,
            np.array(res["contact"]).reshape(-1))


def case_args(cases, i):
    return (cases["P0"][i], cases["Dp"][i], cases["n"][i], cases["l"][i],
            cases["mu"][i], cases["u0"][i])


def eval_oracle(method, cases, paths=None):
    step = ORACLES[method]
    N = len(cases["mu"])
    d, P, k, c = np.zeros((N, 3)), np.zeros((N, 3)), np.zeros((N, 3)), np.zeros(N)
    for i in range(N):
        path = [] if paths is not None else None
        d[i], P[i], k[i], c[i] = step(*case_args(cases, i), path=path)
        if paths is not None:
            paths.append(path)
    return d, P, k, c


# ---------------------------------------------------------------------------
# error metric
# ---------------------------------------------------------------------------

def _norm(x):
    return np.linalg.norm(x, axis=-1)


def errors(method, P0, Dp, n, l, u0, out_o, out_f):
    """Per-case relative errors (err_delta, err_P, err_k) and flag mismatch."""
    P0, Dp, n, l, u0 = (np.atleast_2d(x) for x in (P0, Dp, n, l, u0))
    Dp = Dp.reshape(-1, 3, 3)
    do, Po, ko, co = (np.atleast_1d(x) for x in out_o)
    df, Pf, kf, cf = (np.atleast_1d(x) for x in out_f)
    do, Po, ko, df, Pf, kf = (x.reshape(-1, 3) for x in (do, Po, ko, df, Pf, kf))
    s = P0 - np.sum(n * P0, axis=1)[:, None] * n
    lt = l - np.sum(n * l, axis=1)[:, None] * n
    ns, nlt = _norm(s), _norm(lt)
    lifted = (co == 0) | (cf == 0)
    terms = [_norm(l), _norm(do), _norm(df), np.where(lifted, _norm(u0), 0.0)]
    if method == "implicit":
        terms.append(_norm(ko))
    else:
        terms += [np.abs(ko[:, 0]) * ns, np.abs(ko[:, 1]) * nlt, np.abs(ko[:, 2])]
    Sd = np.max(terms, axis=0)
    Sd_safe = np.where(Sd > 0, Sd, 1.0)
    normDp = np.linalg.norm(Dp, 2, axis=(1, 2))
    SP = np.max([_norm(P0), _norm(Po), _norm(Pf), normDp * Sd], axis=0)
    SP_safe = np.where(SP > 0, SP, 1.0)
    with np.errstate(invalid="ignore", over="ignore"):
        e_d = _norm(do - df) / Sd_safe
        e_P = _norm(Po - Pf) / SP_safe
        if method == "implicit":
            e_k = _norm(ko - kf) / Sd_safe
        else:
            dk = np.abs(ko - kf)
            e_k1 = np.where(ns > 0, dk[:, 0] * ns / Sd_safe, dk[:, 0])
            e_k2 = np.where(nlt > 0, dk[:, 1] * nlt / Sd_safe, dk[:, 1])
            e_k3 = dk[:, 2] / Sd_safe
            e_k = np.max([e_k1, e_k2, e_k3], axis=0)
    err = np.max([e_d, e_P, e_k], axis=0)
    finite = np.all(np.isfinite(np.c_[df, Pf, kf, cf]), axis=1)
    err = np.where(finite, err, np.inf)
    err = np.where(np.isnan(err), np.inf, err)
    return err, e_d, e_P, e_k, co != cf


# ---------------------------------------------------------------------------
# classification of failing cases
# ---------------------------------------------------------------------------

def _perturb(args, eta, rng):
    """Norm-wise relative perturbation of a case (the backward-error model of
    round-off): each input moves by at most eta times its own norm, P0 by eta
    times |P0| + |Dp||l| (the size of P0 + Dp l, so P0 = 0 is perturbed too),
    n is renormalised, mu is scaled by (1 + eta u) so mu = 0 stays 0."""
    P0, Dp, n, l, mu, u0 = args
    nrm = np.linalg.norm
    U = lambda shape: rng.uniform(-1.0, 1.0, shape)  # noqa: E731
    P0s = nrm(P0) + nrm(Dp, 2) * nrm(l)
    n2 = n + eta * U(3)
    return (P0 + eta * P0s * U(3), Dp + eta * nrm(Dp, 2) * U((3, 3)),
            n2 / nrm(n2), l + eta * nrm(l) * U(3), mu * (1.0 + eta * U(())),
            u0 + eta * nrm(u0) * U(3))


def _single_err(method, args, out_o, out_f):
    P0, Dp, n, l, mu, u0 = args
    err, *_rest, flag = errors(method, P0, Dp, n, l, u0, out_o, out_f)
    return float(err[0]), bool(flag[0])


def _flips(path0, paths):
    base = dict(path0)
    out = set()
    for p2 in paths:
        out |= {k for k, v in p2 if base.get(k, "absent") != v}
        out |= {k for k in base if k not in dict(p2)}
    return out


def classify(method, args, path0, out_f, seed=0, extended=False):
    """Return (category, detail) for one failing case; see the module docstring.

    ``extended``: before calling a case a disagreement, search EXTENDED_DRAWS
    more round-off perturbations for a branch flip (rare flips, e.g. the sign
    of a vector that is pure round-off)."""
    step = ORACLES[method]
    rng = np.random.default_rng(seed)
    out_o = step(*args)
    err, flag = _single_err(method, args, out_o, out_f)
    # round-off spread of the oracle itself: how far its own output moves
    # under perturbations of the inputs by 0.5 to 4.5 ulp (whatever branches
    # it then takes); stop as soon as it covers the disagreement
    spread, flag_flips, round_paths = 0.0, False, []

    def round_draws(count):
        nonlocal spread, flag_flips
        for eta in ROUND_ETAS:
            for _ in range(count):
                p2 = []
                o2 = step(*_perturb(args, eta, rng), path=p2)
                e2, f2 = _single_err(method, args, out_o, o2)
                spread = max(spread, e2)
                flag_flips |= f2
                if p2 != path0 and p2 not in round_paths:
                    round_paths.append(p2)
                if (flag_flips or not flag) and err <= SPREAD_FACTOR * spread:
                    return True
        return False

    def other_branches(paths):
        best = np.inf
        for p2 in paths:
            try:
                o3 = step(*args, force=dict(p2))
            except (ZeroDivisionError, ValueError, OverflowError):
                continue   # a forced decision can divide by an exact zero
            e3, f3 = _single_err(method, args, o3, out_f)
            if not f3:
                best = min(best, e3)
        return best

    det = dict(err=err, flag=flag, path=path0)
    if round_draws(ROUND_DRAWS):
        return "roundoff", dict(det, spread=spread,
                                round_flips=sorted(_flips(path0, round_paths)))
    # branch thresholds within THRESH_ETA: the other side, on the same inputs
    alt_paths = list(round_paths)
    for eta in THRESH_ETA:
        for _ in range(THRESH_DRAWS):
            p2 = []
            step(*_perturb(args, eta, rng), path=p2)
            if p2 != path0 and p2 not in alt_paths:
                alt_paths.append(p2)
    tol = max(TOL, SPREAD_FACTOR * spread)
    best = other_branches(alt_paths)
    if best > tol and extended and not round_paths:
        if round_draws(EXTENDED_DRAWS):
            return "roundoff", dict(det, spread=spread,
                                    round_flips=sorted(_flips(path0, round_paths)))
        new = [p2 for p2 in round_paths if p2 not in alt_paths]
        alt_paths += new
        tol = max(TOL, SPREAD_FACTOR * spread)
        best = min(best, other_branches(new))
    det.update(spread=spread, other_branch_err=best, flips=sorted(_flips(path0, alt_paths)))
    if best <= tol:
        return "threshold", det
    if round_paths:
        det["round_flips"] = sorted(_flips(path0, round_paths))
        return "at-threshold", det
    return "disagree", det


def compare(method, cases, f=None):
    """Full comparison of one method; returns a report dict."""
    if f is None:
        from symcushion.contact import contact_step
        f = contact_step(method)
    t0 = time.time()
    out_f = eval_function(f, cases)
    t1 = time.time()
    paths = []
    out_o = eval_oracle(method, cases, paths)
    t2 = time.time()
    err, e_d, e_P, e_k, flag = errors(method, cases["P0"], cases["Dp"], cases["n"],
                                      cases["l"], cases["u0"], out_o, out_f)
    bad = np.flatnonzero((err > TOL) | flag)
    cats = {"roundoff": [], "threshold": [], "at-threshold": [], "disagree": []}
    details = {}
    for i in bad:
        if len(cats["disagree"]) >= MAX_DISAGREE_CLASSIFIED:
            # the test fails anyway; keep the runtime bounded
            cats["disagree"].append(int(i))
            details[int(i)] = dict(err=float(err[i]), flag=bool(flag[i]),
                                   note="not classified")
            continue
        cat, det = classify(method, case_args(cases, i), paths[i],
                            tuple(x[i] for x in out_f), seed=int(i),
                            extended=len(cats["disagree"]) < EXTENDED_WHILE)
        cats[cat].append(int(i))
        details[int(i)] = det
    ok = np.setdiff1d(np.arange(len(err)), bad)
    t3 = time.time()
    per_kind = {}
    for kind in oc.KINDS:
        m = cases["kind"] == kind
        per_kind[kind] = dict(
            count=int(m.sum()),
            worst_ok=float(np.max(err[np.intersect1d(ok, np.flatnonzero(m))], initial=0.0)),
            excused=sum(cases["kind"][j] == kind for c in EXCUSED for j in cats[c]),
            disagree=sum(cases["kind"][j] == kind for j in cats["disagree"]))
    return dict(method=method, n=len(err), err=err, e_d=e_d, e_P=e_P, e_k=e_k,
                flag=flag, bad=bad, cats=cats, details=details,
                worst_all=float(np.max(np.where(np.isfinite(err), err, 0.0))),
                worst_ok=float(np.max(err[ok], initial=0.0)),
                per_kind=per_kind, out_f=out_f, out_o=out_o, paths=paths,
                times=(t1 - t0, t2 - t1, t3 - t2))


def format_report(rep, cases, limit=5):
    lines = [f"== {rep['method']}: {rep['n']} cases; "
             f"worst error among cases within TOL {rep['worst_ok']:.3g} "
             f"(TOL {TOL:g}), over all cases {rep['worst_all']:.3g}; "
             f"function {rep['times'][0]:.1f}s, oracle "
             f"{rep['times'][1]:.1f}s, classification {rep['times'][2]:.1f}s"]
    q = np.quantile(rep["err"][np.isfinite(rep["err"])], [0.5, 0.9, 0.99])
    lines.append(f"   error quantiles 50/90/99 %: {q[0]:.2g} {q[1]:.2g} {q[2]:.2g}")
    for kind, pk in rep["per_kind"].items():
        lines.append(f"   {kind:9s} n={pk['count']:5d} worst={pk['worst_ok']:.3g} "
                     f"excused={pk['excused']} disagree={pk['disagree']}")
    for cat in rep["cats"]:
        idx = rep["cats"][cat]
        worst = max((rep["err"][i] for i in idx), default=0.0)
        lines.append(f"   {cat}: {len(idx)}" + (f" (largest error {worst:.3g})" if idx else ""))
        if cat == "disagree" and idx:
            groups = {}
            unclassified = [i for i in idx if rep["details"][i].get("note") == "not classified"]
            if unclassified:
                lines.append(f"     ({len(unclassified)} not classified: more than "
                             f"{MAX_DISAGREE_CLASSIFIED} disagreements)")
            for i in idx:
                if i in unclassified:
                    continue
                key = " ".join(f"{k}={v}" for k, v in rep["paths"][i])
                groups[key] = groups.get(key, 0) + 1
            for key, cnt in sorted(groups.items(), key=lambda kv: -kv[1])[:4]:
                lines.append(f"     {cnt} with oracle path: {key}")
        for i in idx[:limit]:
            det = rep["details"][i]
            lines.append(f"     case {i} ({cases['kind'][i]}, {cases['cone'][i]}, "
                         f"{cases['motion'][i]}, mu={cases['mu'][i]:.3g}): "
                         + ", ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}"
                                     for k, v in det.items() if k != "path"))
    return "\n".join(lines)


# ---------------------------------------------------------------------------
# pytest
# ---------------------------------------------------------------------------

@pytest.fixture(scope="module")
def cases():
    return make_cases()


@pytest.mark.parametrize("method", COMPARED)
def test_frictionless_function_matches_oracle(method, cases):
    """contact_step(method, friction=False) -- the smaller mu = 0 graph --
    against the oracle on the mu = 0 cases (its docstring: 'The mu = 0
    results equal those of the full graph')."""
    contact = pytest.importorskip("symcushion.contact")
    f = contact.contact_step(method, friction=False)
    sub = {key: val[cases["mu"] == 0.0] for key, val in cases.items()}
    assert len(sub["mu"]) > 1000
    rep = compare(method, sub, f)
    print("\n(friction=False) " + format_report(rep, sub))
    excused = sum(len(rep["cats"][c]) for c in EXCUSED)
    assert not rep["cats"]["disagree"], format_report(rep, sub, limit=10)
    # mu = 0 is where the printed step's sqrt(eps) loss concentrates
    assert excused <= {"paper": 0.45, "robust": 0.07, "implicit": 0.05}[method] * rep["n"]


# Minimal cases found by the comparison (see the module docstring of the
# report); each is (method, friction, P0, Dp, n, l, mu, u0, expected), with
# expected = (delta, P, k, contact) the outcome the spec prescribes.
REPRODUCERS = {
    # spec section 3, a removable pole at mu = 0: K = diag(10, -5), the root
    # r1 = 5 of det(K + lam I) has residue v = adj(K + 5 I) p = 0, so it is
    # not an active pole (spec: 'Changed from "the largest root"'); F_lo =
    # F(0) = 0 and the foot slides frictionlessly, g = K^-1 p = (0.04, 0, 0),
    # P = (0, 0, 1.01).  Before the spec change the full graph lifted off
    # (F_lo = lam_p = 5 > 0) while the friction=False graph slid; both must
    # now slide.
    "implicit friction=False: pole at mu = 0": (
        "implicit", False, [0.3, 0.0, 1.0], [[10, 0, 0], [0, -5, 0], [0, 0, 10]],
        [0, 0, 1], [0.01, 0, 0.001], 0.0, [0.03, 0.0, 0.1],
        ([-0.03, 0.0, 0.001], [0.0, 0.0, 1.01], [0.04, 0.0, 0.0], 1.0)),
    "implicit friction=True: pole at mu = 0": (
        "implicit", True, [0.3, 0.0, 1.0], [[10, 0, 0], [0, -5, 0], [0, 0, 10]],
        [0, 0, 1], [0.01, 0, 0.001], 0.0, [0.03, 0.0, 0.1],
        ([-0.03, 0.0, 0.001], [0.0, 0.0, 1.01], [0.04, 0.0, 0.0], 1.0)),
}


@pytest.mark.parametrize("name", sorted(REPRODUCERS))
def test_reproducer(name):
    contact = pytest.importorskip("symcushion.contact")
    method, friction, *case, expected = REPRODUCERS[name]
    args = tuple(np.asarray(x, dtype=float) for x in case)
    out_o = ORACLES[method](*args)
    # the oracle gives the outcome the spec prescribes ...
    exp = tuple(np.asarray(x, dtype=float) for x in expected[:3]) + (expected[3],)
    err, flag = _single_err(method, args, out_o, exp)
    assert not flag and err <= TOL, (name, out_o, expected)
    # ... and so does the Function
    res = contact.contact_step(method, friction=friction)(*args)
    out_f = tuple(np.array(x).ravel() for x in res)
    err, flag = _single_err(method, args, out_o, (out_f[0], out_f[1], out_f[2], out_f[3][0]))
    assert not flag and err <= TOL, (name, out_o, out_f)


def test_oracle_reproduces_notes_item6():
    """docs/paper-notes.md §3 item 6 / spec section 3 check, on the oracle alone."""
    P0, Dp, n = np.array([0.3, 0.0, 1.0]), 10.0 * np.eye(3), np.array([0.0, 0.0, 1.0])
    l, mu, u0 = np.array([0.0, 0.01, 0.0]), 0.3, np.array([0.03, 0.0, 0.1])
    _, P, _, c = oc.implicit_step(P0, Dp, n, l, mu, u0)
    assert c == 1.0
    assert np.allclose(P, [0.28460498941515416, 0.09486832980505139, 1.0], rtol=0, atol=1e-12)
    _, P, _, _ = oc.paper_step(P0, Dp, n, l, mu, u0)
    assert np.allclose(P, P0, rtol=0, atol=1e-12)   # the printed step does not turn P


def test_case_generator_covers_the_brief(cases):
    assert len(cases["mu"]) >= 10_000
    for kind in oc.KINDS:
        assert np.sum(cases["kind"] == kind) == CASES_PER_KIND
    assert np.any(cases["mu"] == 0.0) and np.all((cases["mu"] >= 0) & (cases["mu"] <= 2))
    for lab in ("inside", "on", "outside", "tensile", "zero"):
        assert np.any(cases["cone"] == lab)
    nl = np.sum(cases["n"] * cases["l"], axis=1)
    assert np.any(nl > 0) and np.any(nl < 0) and np.any(nl == 0.0)
    cond = np.linalg.cond(cases["Dp"][cases["kind"] == "singular"])
    assert cond.max() > 5e7 and cond.min() > 5e3
    # on-cone P0: C0 = round-off
    on = cases["cone"] == "on"
    P0, n, mu = cases["P0"][on], cases["n"][on], cases["mu"][on]
    C0 = np.sum(P0 * P0, 1) - (1 + mu ** 2) * np.sum(n * P0, 1) ** 2
    assert np.all(np.abs(C0) <= 1e-14 * (1 + mu ** 2) * np.sum(P0 * P0, 1))


def test_implicit_two_roots_takes_the_small_slip():
    """Hand-sized case with two slip roots, on the oracle (= the spec).

    F(0) = 0.073 > 0, F < 0 on (0.412, 5.402): roots lam = 0.412 and 5.402.
    The first spec (a bracketed Newton iteration from lam = 0) lifted off
    here; the spec now takes the solution of least slip,
    g = (1.028, 1.779, 0), n.P = 9.57."""
    P0, Dp, n, l, mu = ([7.04, 10.4, 10.8],
                        [[0.901, 0.312, 0.291], [0.312, 0.183, 0.243],
                         [0.291, 0.243, 1.06]], [0, 0, 1], [0.544, -1.28, -0.328], 1.16)
    args = [np.asarray(x, dtype=float) for x in (P0, Dp, n, l)] + [mu]
    sols = oc.implicit_solutions(*args)
    assert sum(N > 0 for _, N in sols) == 2
    _, P, g, c = oc.implicit_step(*args, np.zeros(3))
    assert c == 1.0
    np.testing.assert_allclose(g, [1.028, 1.779, 0.0], atol=1e-3)
    assert abs(P[2] - 9.57) <= 0.01


def test_implicit_removable_pole_mu0():
    """Was a known failure of the first spec draft (a removable pole lifted
    the foot off); the active-pole rule of spec section 3 fixed it.
    K = diag(10, -5): det(K + lam I) = 0 at lam = 5, but the residue
    v = adj(K + 5 I) p = 0, so the pole is not active; F_lo = F(0) = 0 and
    the step finds the frictionless slide g = (0.04, 0, 0), n.P = 1.01."""
    args = [np.asarray(x, dtype=float) for x in
            ([0.3, 0, 1], [[10, 0, 0], [0, -5, 0], [0, 0, 10]], [0, 0, 1],
             [0.01, 0, 0.001])] + [0.0]
    sols = oc.implicit_solutions(*args)
    assert any(N > 0 for _, N in sols)               # a slip solution exists
    d, P, g, c = oc.implicit_step(*args, np.zeros(3))
    assert c == 1.0                                  # ... and the step finds it
    assert np.allclose(g, [0.04, 0, 0], rtol=0, atol=1e-14)
    assert np.allclose(P, [0, 0, 1.01], rtol=0, atol=1e-14)


@pytest.mark.parametrize("method", COMPARED)
def test_function_matches_oracle(method, cases):
    contact = pytest.importorskip("symcushion.contact")
    f = contact.contact_step(method)
    rep = compare(method, cases, f)
    print("\n" + format_report(rep, cases))
    excused = sum(len(rep["cats"][c]) for c in EXCUSED)
    assert not rep["cats"]["disagree"], format_report(rep, cases, limit=10)
    assert excused <= MAX_EXCUSED_FRACTION[method] * rep["n"], format_report(rep, cases)
    assert rep["worst_ok"] <= TOL


if __name__ == "__main__":
    cs = make_cases()
    from symcushion.contact import contact_step
    for m in sys.argv[1:] or METHODS:
        print(format_report(compare(m, cs, contact_step(m)), cs, limit=20))
