"""Study (issue 22, session 39): why the motion estimate decomposes ``A^T A`` (eqs. 6-7, 10),
and what cheaper decompositions would cost, on the systems of a real run.

``benchmarks/bench_real.py --dump-core-inputs DIR`` first; then::

    .venv/bin/python benchmarks/studies/rank_spectrum_real.py DIR --camera cam01 --every 20

Tracks one camera serially and keeps every ``A^T A`` that
:func:`~core.tracking.motion.rank_decompositions` decomposes (the tracker itself is unchanged).
Prints the core's CPU and the share of those calls, then, over all systems:

* the spectrum around the rank threshold ``tau``: the structural null directions (singular
  values below ``1e-6 sigma_1``: joints not measured, the depth motion), the singular values
  the threshold sets aside beyond them, the smallest kept and the largest set-aside
  ``sigma_i / sigma_1`` -- a Cholesky or ``solve`` of the normal equations (with the
  structural null space regularised away) equals eq. 10 only where nothing else is set aside;
* the CPU time of the same calls (same batch sizes) with ``eigh`` (the tracker), ``eigvalsh``
  (singular values only), ``eigh`` in float32, ``cholesky`` and ``inv``;
* float32 ``eigh`` against float64: ranks that differ, and the largest differences of eq. 7's
  ``A^+ b`` (random ``b``, given as ``A^T b``) and eq. 10's ``W W^T y`` (random ``y``), relative
  to their norms.
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2]))

from benchmarks.real.core_replay import load_case  # noqa: E402
from core.tracking import motion, track_keyframes  # noqa: E402


def _solve_parts(eig, vec, tau, atb, y):
    """Eq. 7's ``A^+ b`` from ``A^T b`` and eq. 10's ``W W^T y`` from an eigh of ``A^T A``."""
    sigma = np.sqrt(np.maximum(eig[:, ::-1], 0.0))
    v = vec[:, :, ::-1]
    rank = np.where(sigma[:, 0] > 0, np.sum(sigma >= tau[:, None] * sigma[:, :1], axis=1), 0)
    kept = np.arange(sigma.shape[1])[None] < rank[:, None]
    inv = np.where(kept, 1.0 / np.where(kept, sigma, 1.0) ** 2, 0.0)
    part = np.einsum("fpk,fk->fp", v, np.einsum("fpk,fp->fk", v, atb) * inv)
    null = np.einsum("fpk,fk->fp", v, np.einsum("fpk,fp->fk", v, y) * ~kept)
    return rank, part, null


def _cpu(fn, stacks, repeat):
    start = time.process_time()
    for _ in range(repeat):
        for g in stacks:
            fn(g)
    return (time.process_time() - start) / repeat


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dump")
    ap.add_argument("--camera", default="cam01")
    ap.add_argument("--every", type=int, default=20)
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    case = load_case(args.dump, args.camera, args.every)
    frames = np.asarray(case["frames"])
    keys = np.asarray(case["key_frames"]) - 1
    grams, taus = [], []
    original = motion.rank_decompositions

    inside = [0.0, 0.0]

    def kept(a, tau):
        start = time.process_time()
        out = original(a, tau)
        inside[0] += time.process_time() - start
        start = time.process_time()
        a = np.asarray(a, dtype=float)
        grams.append(np.matmul(np.swapaxes(a, 1, 2), a))
        taus.append(np.broadcast_to(np.asarray(tau, dtype=float), (len(a),)).copy())
        inside[1] += time.process_time() - start            # kept out of the core's time
        return out

    motion.rank_decompositions = kept
    start = time.process_time()
    track_keyframes(case["problem"], frames, keys, case["key_roots"], case["key_locals"],
                    case["options"], processes=1)
    core = time.process_time() - start - inside[1]
    motion.rank_decompositions = original
    print(f"the core, CPU {core:.2f} s; rank_decompositions (A^T A and eigh) {inside[0]:.2f} s "
          f"({100 * inside[0] / core:.1f} %)")
    g = np.concatenate(grams)
    tau = np.concatenate(taus)
    p = g.shape[1]
    eig = np.linalg.eigvalsh(g)[:, ::-1]
    ratio = np.sqrt(np.maximum(eig, 0.0) / eig[:, :1])
    structural = (ratio < 1e-6).sum(axis=1)
    below = (ratio < tau[:, None]).sum(axis=1) - structural
    rank = p - structural - below
    smallest_kept = np.array([r[k - 1] for r, k in zip(ratio, rank)])
    largest_aside = np.array([r[k] if s + b else np.nan
                              for r, k, s, b in zip(ratio, rank, structural, below)])
    print(f"{len(grams)} calls, {len(g)} systems, P = {p}")
    print(f"structural null directions per system: {np.bincount(structural).tolist()} "
          f"(count of systems with 0, 1, ...)")
    print(f"singular values set aside by tau beyond them: min {below.min()}, median "
          f"{int(np.median(below))}, max {below.max()}; systems with none: {(below == 0).sum()}")
    print(f"rank: min {rank.min()}, median {int(np.median(rank))}, max {rank.max()}")
    print(f"smallest kept sigma/sigma_1: median {np.median(smallest_kept / tau):.3f} tau "
          f"(min {np.min(smallest_kept / tau):.4f} tau); largest set aside (beyond structural): "
          f"median {np.nanmedian(largest_aside / tau):.3f} tau "
          f"(max {np.nanmax(largest_aside / tau):.4f} tau)")
    g32 = [x.astype(np.float32) for x in grams]
    for name, fn, stacks in (("eigh (float64, the tracker)", np.linalg.eigh, grams),
                             ("eigvalsh (float64)", np.linalg.eigvalsh, grams),
                             ("eigh (float32)", np.linalg.eigh, g32),
                             ("inv (float64)", np.linalg.inv,
                              [x + np.eye(p) * np.trace(x, axis1=1, axis2=2)[:, None, None]
                               for x in grams]),
                             ("cholesky (float64)", np.linalg.cholesky,
                              [x + np.eye(p) * np.trace(x, axis1=1, axis2=2)[:, None, None]
                               for x in grams])):
        print(f"  CPU of the {len(grams)} calls, {name:28s} {_cpu(fn, stacks, args.repeat):.3f} s")
    rng = np.random.default_rng(0)
    atb = np.einsum("fpq,fq->fp", g, rng.normal(size=(len(g), p)))     # in the range of A^T
    y = rng.normal(size=(len(g), p))
    r64, part64, null64 = _solve_parts(*np.linalg.eigh(g), tau, atb, y)
    e32, v32 = np.linalg.eigh(g.astype(np.float32))
    r32, part32, null32 = _solve_parts(e32.astype(float), v32.astype(float), tau, atb, y)
    rel = lambda a, b: np.linalg.norm(a - b, axis=1) / np.linalg.norm(b, axis=1)  # noqa: E731
    same = r32 == r64
    print(f"float32 eigh: rank differs in {np.sum(~same)} of {len(g)} systems; where equal, "
          f"A^+ b relative difference median {np.median(rel(part32, part64)[same]):.1e} "
          f"max {np.max(rel(part32, part64)[same]):.1e}, W W^T y max "
          f"{np.max(rel(null32, null64)[same]):.1e}")


if __name__ == "__main__":
    main()
