"""A cheap cloth pass for loose garment parts (the robe's skirt): position-based dynamics
on top of the skinned shape, per frame, before the intersection fix.

The loose part is skinned with smoothed weights (:mod:`humv_usd.clothing.fit`): that shape
swings rigidly with the mean of the thighs. Here its vertices get inertia: each frame is
split into :data:`SUBSTEPS` steps of h = 1 / (fps * SUBSTEPS) of position-based dynamics
(Müller et al. 2007, "Position based dynamics", J. Vis. Commun. Image R. 18:109-118):

1. predict: v <- v (1 - DAMPING h) + g h,  p = x + v h  (symplectic Euler, gravity
   g = -9.81 m s^-2 along z);
2. follow: p <- p + a (s - p), s the skinned position (interpolated linearly within the
   frame), a = 1 - exp(-h / tau) with tau = :data:`TAU_HEM` x (1 - u)^2, u = 0 at the hem
   and 1 at the waistband: the waistband is pinned to the body, the hem lags the most
   (a per-vertex zero-length spring to the skinned shape, integrated exactly over h);
3. stretch: :data:`ITERATIONS` Jacobi passes of PBD distance constraints on the part's
   quad edges and diagonals (rest lengths of the fitted rest mesh), stiffness
   :data:`STIFFNESS` per pass, inverse masses tau / max(tau) (the waistband does not move);
4. tether: no vertex farther than :data:`MAX_LAG` from its skinned position (a long-range
   attachment, Kim, Chentanez & Müller 2012, "Long range attachments", SCA);
5. collide: vertices nearer than the minimum gap to the frame's posed body are projected
   out to it along the body normal (closest point, as the fix does);
6. v = (p - x) / h, x = p.

After the pass the usual per-frame fix (:func:`humv_usd.clothing.collide.push_out`) keeps
every vertex outside the body and the minimum gap off it (wedges between the legs included),
and its result is what the next frame starts from. The collision in step 5 uses the body at
the end of the frame for every sub-step (a fast leg can overtake a lagging hem within a
frame; the hem is then pushed out to the leg's surface, sliding along it rather than being
caught by it).

Limits (stated, not hidden): no self-collision of the cloth, no cloth-cloth collision with
the other parts of the garment, no bending stiffness (folds come from the skinned shape
and the lag only), no wind, and the clip starts at rest (frame 0 is the skinned shape with
zero velocity; the lag builds over the first ~0.2 s). Only parts marked ``loose`` are
simulated; a person who does not move gets the skinned shape.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Sub-steps per frame.
SUBSTEPS = 4
#: Follow time constant at the hem [s] (the waistband: 0, pinned).
TAU_HEM = 0.06
#: Linear velocity damping [1/s].
DAMPING = 4.0
#: Jacobi passes of the stretch constraints per sub-step and their stiffness.
ITERATIONS = 4
STIFFNESS = 0.8
#: Largest distance [m] from the skinned shape (tether).
MAX_LAG = 0.08
GRAVITY = np.array([0.0, 0.0, -9.81])


@dataclass
class Drape:
    """State of one loose part over the frames (skeleton space)."""

    vertices: np.ndarray  # (m,) garment vertex ids of the part
    edges: np.ndarray  # (e, 2) indices into ``vertices``
    rest_length: np.ndarray  # (e,)
    tau: np.ndarray  # (m,) follow time constant [s]
    x: np.ndarray | None = None
    v: np.ndarray | None = None
    target: np.ndarray | None = None

    @classmethod
    def for_part(cls, rest_points: np.ndarray, quads: np.ndarray, vertices: np.ndarray) -> Drape:
        """A drape of the garment vertices ``vertices`` whose faces are ``quads`` (garment
        vertex ids, (q, 4)); rest lengths from ``rest_points`` (the garment's rest mesh)."""
        local = np.full(int(quads.max()) + 1, -1)
        local[vertices] = np.arange(len(vertices))
        q = local[quads]
        e = np.concatenate(
            [q[:, [0, 1]], q[:, [1, 2]], q[:, [2, 3]], q[:, [3, 0]], q[:, [0, 2]], q[:, [1, 3]]]
        )  # edges + shear diagonals
        e = np.unique(np.sort(e, axis=1), axis=0)
        p = rest_points[vertices]
        z = p[:, 2]
        u = (z - z.min()) / max(float(np.ptp(z)), 1e-9)  # 0 hem .. 1 waistband
        return cls(vertices, e, np.linalg.norm(p[e[:, 0]] - p[e[:, 1]], axis=1), TAU_HEM * (1.0 - u) ** 2)

    def step(self, skinned: np.ndarray, dt: float, body=None, gap: float = 0.0) -> np.ndarray:
        """The part's positions this frame (m, 3) given its skinned positions; ``dt`` the
        frame time [s] (the first call returns ``skinned``). ``body``: the frame's posed body
        (:class:`humv_usd.geometry.mesh.Surface`): after each sub-step vertices nearer
        than ``gap`` are projected out to it along the body normal (step 6)."""
        s1 = np.asarray(skinned, dtype=np.float64)
        if self.x is None or dt <= 0:
            self.x, self.v, self.target = s1.copy(), np.zeros_like(s1), s1.copy()
            return self.x.copy()
        h = dt / SUBSTEPS
        a = 1.0 - np.exp(-h / np.maximum(self.tau, 1e-12))[:, None]
        i, j = self.edges[:, 0], self.edges[:, 1]
        count = np.bincount(self.edges.ravel(), minlength=len(s1)).astype(float)[:, None]
        w = self.tau / max(float(self.tau.max()), 1e-12)  # inverse mass: 0 pinned
        wsum = np.maximum(w[i] + w[j], 1e-12)
        wi, wj = (w[i] / wsum)[:, None], (w[j] / wsum)[:, None]
        x, v, s0 = self.x, self.v, self.target
        for k in range(1, SUBSTEPS + 1):
            s = s0 + (s1 - s0) * (k / SUBSTEPS)
            v = v * max(1.0 - DAMPING * h, 0.0) + GRAVITY * h
            p = x + v * h
            p += a * (s - p)
            for _ in range(ITERATIONS):
                d = p[j] - p[i]
                length = np.linalg.norm(d, axis=1)
                corr = (STIFFNESS * (length - self.rest_length) / np.maximum(length, 1e-12))[:, None] * d
                delta = np.zeros_like(p)
                np.add.at(delta, i, wi * corr)
                np.add.at(delta, j, -wj * corr)
                p += delta / np.maximum(count, 1.0)
            off = p - s
            far = np.linalg.norm(off, axis=1)
            over = far > MAX_LAG
            p[over] = s[over] + off[over] * (MAX_LAG / far[over])[:, None]
            if body is not None:
                near = body.closest(p)
                low = near.signed < gap
                p[low] = near.point[low] + near.normal[low] * (gap + 1e-4)
            v = (p - x) / h
            x = p
        self.x, self.v, self.target = x, v, s1
        return x.copy()

    def settle(self, fixed: np.ndarray) -> None:
        """Take the positions after the intersection fix as this frame's state (velocity
        kept: the fix is a collision response, not a force)."""
        self.x = np.asarray(fixed, dtype=np.float64).copy()
