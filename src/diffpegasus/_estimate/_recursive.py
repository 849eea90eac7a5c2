"""Recursive (real-time) estimation: a state, a jit-compiled update per sample, and
the current estimates with error bounds at any time.

The problem is a linear regression sample by sample: `q` equations

    y_k = H_k theta + o_k        (or  d/dt y = H theta + o  for a derivative row)

in `p` parameters, with `H_k` `(q, p)`, `y_k`, `o_k` `(q,)` (see
[`model_regression`][] for the equations of a model file). A derivative row (a state
equation) is differenced between samples, `(y_k - y_(k-1)) / dt` against the
regressors and offsets averaged over the two samples: second-order at the midpoint,
no delay, no smoothing filter.

Two estimators share the contract ([`AbstractRecursiveEstimator`][]: `init`,
`update`, `estimates`):

- [`RecursiveLeastSquares`][]: exponentially weighted least squares (forgetting
  factor `lam`), equations weighted by their running residual variance.
- [`RecursiveFourier`][]: Morelli's recursive Fourier transform equation error: the
  running transforms (with the same forgetting) of the regressors and regressands at
  a few frequencies, solved as a complex least-squares problem whenever estimates
  are asked for. Only the band of the rigid-body dynamics enters, so the
  high-frequency noise of differenced signals never does.

**Error bounds** (Grauer & Morelli's point: recursive bounds must account for
coloured residuals to match the scatter). For least squares with forgetting the
estimate's error is `P sum_i w_i s_i`, `w_i = lam^(k-i)`, `s_i` the sample's score,
so its covariance is the sandwich `P (sum_ij w_i w_j E[s_i s_j^T]) P`. Least squares
estimates the middle by batch means: the scores summed over blocks of `2^j` samples
(a ladder `j = 0 ... levels - 1`, every block length at once), the outer products of
the block sums summed; block sums longer than the residuals' correlation are
independent. Each score is kept as `a_i - G_i theta`, so the block sums are
evaluated with the current estimate; the fitted residuals' loss `(2 cross - 1)
sum_b G_b V G_b` is solved for (`cross` 1 without forgetting, from the forgetting's
weights with it: `_centering_cross`). `stderr` is the bound of single samples
(white residuals); `stderr_corrected` the one from the longest blocks that leave at
least three (effectively, counted from how the information is spread over them),
extrapolated in one over the block length from the ladder's blocks of a quarter and
an eighth of that length (a block misses the correlation across its ends), and
the 95% band (`halfwidth`) the Student-t quantile at their number times the share
Satterthwaite's count of that extrapolated bound keeps (`_extrapolated_share`,
summed over the groups of blocks: segment sums, not the pairs of blocks), scaled
for the lower tail: Satterthwaite's two moments miss the floor that the older
blocks make under a memory (their shares unequal), so the count is scaled by
the degrees of freedom whose Student-t quantile is the exact critical value of
the blocks' own shares over those shares' two-moment count (`_tail_ratio`: the
newest 64 blocks' information is kept per block length). For the
recursive Fourier transform the state equations' two end terms (the
differenced state's transform telescopes to its ends) are estimated with the
parameters, and the bound is the per-frequency sandwich of the batch
method ([`frequency_equation_error`][]) with the cross-frequency terms the finite
transform's leakage makes (`_leakage`: `kappa_fg (S_f + S_g) / 2`), the residual
spectrum `S_f` a quadratic in `sin^2(pi f dt)` with non-negative powers, fitted
to the residual transforms' products
through their expectation at the estimate, `(I - H) S (I - H)^H` at each frequency
(`_smooth_spectrum_bound`), and the band the Student-t quantile at Satterthwaite's
degrees of freedom of that bound. With `bandwidth`, the differenced
state equations are low-passed on both sides, so that their noise (whose power
grows with frequency) does not swamp the band of the dynamics.
"""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool, Complex, Float, Int


class _Spread(eqx.Module):
    """Per block length, forgetting-weighted sums over the blocks of `vec C_b`
    and of `vec C_b vec C_b^T`, `C_b = sum_(i in b) w_i^2 G_i`: how the data are
    spread over the blocks of the memory; and the newest `_RING` completed
    blocks' own `vec C_b` (`ring`, a ring buffer per block length, each as of the
    sample `ring_t` it completed at): the lower tail of the bound's distribution
    needs each block's share, not only the two moments of the shares."""

    g2: Float[Array, "levels pp"]
    g4: Float[Array, "levels pp pp"]
    ring: Float[Array, "levels ring pp"]
    ring_t: Int[Array, "levels ring"]


_RING = 64  # completed blocks kept per block length, as `_BLOCKS_SEEN`: at the
# block length the bound takes (at least three effective blocks) older ones weigh
# less than lam^(2 * 64 * size) under a memory


class RecursiveState(eqx.Module):
    """Everything an estimator carries between samples.

    **Fields:** `theta` `(p,)` the current estimate (least squares) or the last one
    computed (Fourier); `info` `(p, p)` and `rhs` `(p,)` the weighted normal
    equations `sum_i w_i H_i^T H_i` (plus the decaying prior) and `sum_i w_i H_i^T
    y_i`; `r` `(q,)` residual variance per
    equation and `rows` `(q, p + 2, p + 2)` the sums it comes from; `count` samples
    absorbed; `prev_h`, `prev_y`, `prev_o`: the previous sample (for derivative
    rows); `filt` `(2, q, p + 1)` the low-pass state of the differenced rows;
    `block_z` `(levels, p + p^2)` the running block sums of the scores `[a, vec G]`,
    `block_g` `(levels, p^2)` of `w_i^2 vec G_i`, `pairs` `(levels, d, d)` the
    forgetting-weighted outer products of the completed block sums, and `spread` how
    the information is spread over the blocks (and the newest blocks' own), both
    as of the samples `block_t`
    `(levels,)` (the forgetting since then applied when they are read); `fh` `(f, q, p)`, `fy` `(f, q)` the running transforms,
    `phasor`, `rotation` `(f,)`.
    """

    theta: Float[Array, " p"]
    info: Float[Array, "p p"]
    rhs: Float[Array, " p"]
    r: Float[Array, " q"]
    count: Int[Array, ""]
    prev_h: Float[Array, "q p"]
    prev_y: Float[Array, " q"]
    prev_o: Float[Array, " q"]
    block_z: Float[Array, "levels d"]
    block_g: Float[Array, "levels pp"]
    block_t: Int[Array, " levels"]
    pairs: Float[Array, "levels d d"]
    fh: Complex[Array, "f q p"]
    fy: Complex[Array, "f q"]
    phasor: Complex[Array, " f"]
    rotation: Complex[Array, " f"]
    filt: Float[Array, "2 q p1"]
    rows: Float[Array, "q p2 p2"]
    spread: "_Spread"


class RecursiveEstimates(eqx.Module):
    """The estimates at one time: `theta` `(p,)`, `stderr` `(p,)` (white
    residuals), `stderr_corrected` `(p,)` (coloured residuals), `dof` `(p,)` an
    estimate of the effective degrees of freedom of the corrected bound (how many
    independent pieces of data it was estimated from; for least squares those of
    the Student-t band that matches the bound's lower tail), and `halfwidth` `(p,)` the
    half-width of the 95% band: the Student-t quantile at `dof` times
    `stderr_corrected`."""

    theta: Float[Array, " p"]
    stderr: Float[Array, " p"]
    stderr_corrected: Float[Array, " p"]
    dof: Float[Array, " p"]
    halfwidth: Float[Array, " p"]


def _t_quantile(dof, z=1.959963984540054):
    """The Student-t quantile of the normal quantile `z` at `dof` degrees of
    freedom (Cornish-Fisher expansion; within 0.5% of the exact one from 3
    degrees of freedom up)."""
    v = jnp.maximum(dof, 1.0)
    return (
        z
        + (z**3 + z) / (4 * v)
        + (5 * z**5 + 16 * z**3 + 3 * z) / (96 * v**2)
        + (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / (384 * v**3)
    )


def _finish(theta, var, var_c, dof, student):
    """The estimates with the 95% band: the Student-t quantile at `dof` times the
    corrected standard error when `student`, else the normal quantile."""
    sd_c = jnp.sqrt(var_c)
    q = _t_quantile(dof) if student else 1.959963984540054
    return RecursiveEstimates(theta, jnp.sqrt(var), sd_c, dof, q * sd_c)


class AbstractRecursiveEstimator(eqx.Module):
    """A recursive estimator: `init`, then `update` once per sample (jit it, or run
    [`replay`][]), `estimates` at any time.

    **Fields every estimator has:** `forgetting` (the factor `lam` in (0, 1]; the
    memory is about `dt / (1 - lam)` seconds), `derivative` `(q,)` which rows are
    state equations (regressand `d/dt y`), `dt` (s).
    """

    forgetting: eqx.AbstractVar[float]
    derivative: eqx.AbstractVar[tuple[bool, ...]]
    dt: eqx.AbstractVar[float]

    def __check_init__(self):
        if not 0.0 < self.forgetting <= 1.0:
            raise ValueError(f"forgetting must be in (0, 1], got {self.forgetting}")
        if not self.dt > 0:
            raise ValueError(f"dt must be positive, got {self.dt}")

    @abc.abstractmethod
    def init(self, theta0: Float[Array, " p"], prior: float = 1e6) -> RecursiveState:
        """The state before the first sample: estimate `theta0`, prior variance
        `prior` (parameter units squared) on every parameter."""

    @abc.abstractmethod
    def absorb(
        self, state: RecursiveState, h: Float[Array, "q p"], y: Float[Array, " q"]
    ) -> RecursiveState:
        """Take one sample's equations `y = h theta` (rows already differenced)."""

    @abc.abstractmethod
    def estimates(self, state: RecursiveState) -> RecursiveEstimates:
        """The current estimates and their standard errors."""

    def update(
        self,
        state: RecursiveState,
        h: Float[Array, "q p"],
        y: Float[Array, " q"],
        o: Float[Array, " q"],
    ) -> RecursiveState:
        """Absorb the sample `(h, y, o)`: `y = h theta + o`, or for derivative rows
        `d/dt y = h theta + o` (differenced against the previous sample; the first
        sample only primes them)."""
        deriv = jnp.asarray(self.derivative)
        first = state.count == 0
        dy = (y - state.prev_y) / self.dt - 0.5 * (o + state.prev_o)
        hm = 0.5 * (h + state.prev_h)
        filt = state.filt
        bandwidth = getattr(self, "bandwidth", None)
        if bandwidth is not None:
            # both sides of the differenced state equations through the same
            # low-pass (w / (s + w))^2, the differences held over each step:
            # the equation still holds (to the differencing's own order), while
            # the differenced noise, whose power grows with frequency, is cut
            # above `bandwidth`; started at rest on the first difference
            phi, gam = _filter_matrices(bandwidth, self.dt)
            v = jnp.concatenate([hm, dy[:, None]], axis=1)  # (q, p + 1)
            stepped = jnp.einsum("ij,jqc->iqc", phi, filt) + gam[:, None, None] * v
            filt = jnp.where(state.count == 1, jnp.stack([v, 0 * v]), stepped)
            hm, dy = filt[0, :, :-1], filt[0, :, -1]
        use = ~(deriv & first)
        rows_y = jnp.where(deriv, dy, y - o) * use
        rows_h = jnp.where(deriv[:, None], hm, h) * use[:, None]
        state = self.absorb(state, rows_h, rows_y)
        return eqx.tree_at(
            lambda s: (s.prev_h, s.prev_y, s.prev_o, s.count, s.filt),
            state,
            (h, y, o, state.count + 1, filt),
        )


def _filter_matrices(bandwidth, dt):
    """The low-pass `(w / (s + w))^2`, `w = 2 pi bandwidth` rad/s, on the state
    `(F[v], d/dt F[v] / w)`, discretised exactly for an input held over each
    step: `x_k = phi x_(k-1) + gam v_k`."""
    import scipy.linalg

    w = 2.0 * np.pi * bandwidth
    m = np.zeros((3, 3))
    m[:2, :2] = [[0.0, w], [-w, -2.0 * w]]
    m[1, 2] = w
    e = scipy.linalg.expm(m * dt)
    return jnp.asarray(e[:2, :2]), jnp.asarray(e[:2, 2])


def _empty_state(p, q, levels, frequencies, dt, theta0, prior, scores):
    f = jnp.asarray(frequencies, float)
    d = (p + p * p) if scores else 0
    pp = p * p if scores else 0
    rotation = jnp.exp(-2j * jnp.pi * f * dt)
    return RecursiveState(
        theta=jnp.asarray(theta0, float),
        info=jnp.eye(p) / prior,
        rhs=jnp.asarray(theta0, float) / prior,
        r=jnp.full(q, jnp.nan),
        count=jnp.zeros((), int),
        prev_h=jnp.zeros((q, p)),
        prev_y=jnp.zeros(q),
        prev_o=jnp.zeros(q),
        block_z=jnp.zeros((levels, d)),
        block_g=jnp.zeros((levels, pp)),
        block_t=jnp.zeros(levels, int),
        pairs=jnp.zeros((levels, d, d)),
        fh=jnp.zeros((len(f), q, p), rotation.dtype),
        fy=jnp.zeros((len(f), q), rotation.dtype),
        phasor=jnp.ones_like(rotation),
        rotation=rotation,
        filt=jnp.zeros((2, q, p + 1)),
        rows=jnp.zeros((q, p + 2, p + 2)),
        spread=_Spread(
            jnp.zeros((levels, pp)),
            jnp.zeros((levels, pp, pp)),
            jnp.zeros((levels, _RING if scores else 0, pp)),
            jnp.zeros((levels, _RING if scores else 0), int),
        ),
    )


def _inverse(m):
    """Inverse of a symmetric positive definite matrix, scaled to unit diagonal
    first (columns in very different units)."""
    d = jnp.sqrt(jnp.maximum(jnp.diag(m), 1e-300))
    return jnp.linalg.inv(m / jnp.outer(d, d)) / jnp.outer(d, d)


def _solve(m, b):
    """`m^-1 b` for a symmetric positive definite `m`, scaled as [`_inverse`][]."""
    d = jnp.sqrt(jnp.maximum(jnp.diag(m), 1e-300))
    return jnp.linalg.solve(m / jnp.outer(d, d), b / d) / d


def _weights(r):
    """Per equation `sqrt(g / r)`, `g` the geometric mean of the variances `r`: the
    equations weighted against each other by their residual variance, while a
    sample's weight as a whole does not move with the residual level (that would
    let a noise-free stretch outweigh every later sample). 1 before a variance
    exists, and always for a single equation."""
    ok = jnp.isfinite(r) & (r > 0)
    logr = jnp.log(jnp.where(ok, r, 1.0))
    mean = jnp.sum(jnp.where(ok, logr, 0.0)) / jnp.maximum(jnp.sum(ok), 1)
    return jnp.where(ok, jnp.exp(0.5 * (mean - logr)), 1.0)


def _fitted_sandwich(pm, middle, pairs_gg, p, cross=1.0):
    """The diagonal of the estimate's covariance `V` from the pair sums of the
    scores at the estimate (`middle`, `P M P` the plain sandwich).

    The residuals of a fit are smaller than the errors: with `s_i = a_i - G_i
    theta` and the estimate's error `d`, a block's score at the estimate is `U_b -
    G_b d`, and the expected pair sums are `sum_b E[U_b U_b^T] - sum_b (G_b P
    E[U_b U_b^T] + transpose) + K(V)`, `K(V) = sum_b G_b V G_b` (`pairs_gg`, the
    same pair sums of `vec G`). Without forgetting the middle term is `-2 K(V)`;
    with it the block scores' variances fall as `lam^(2 age)` while the estimate
    weighs them by `lam^age`, and the middle term is `-2 cross K(V)`
    ([`_centering_cross`][]), so the pair sums miss `(2 cross - 1) K(V)`. `V = P
    (M + (2 cross - 1) K(V)) P` is linear in `V` and solved as such.
    """
    k = pairs_gg.reshape(p, p, p, p).transpose(0, 3, 1, 2).reshape(p * p, p * p)
    a = jnp.eye(p * p) - (2.0 * cross - 1.0) * jnp.kron(pm, pm) @ k
    v = jnp.linalg.solve(a, (pm @ middle @ pm).reshape(p * p)).reshape(p, p)
    return jnp.diag(v)


_BLOCKS_SEEN = 64  # blocks behind the memory's centering loss; older ones weigh
# less than lam^(2 * 64 * size) once the level leaves at least three effective blocks


def _block_geometry(lam, size, count, seen=_BLOCKS_SEEN):
    """The blocks of `size` samples after `count` samples under the forgetting
    `lam` (the newest partial first), with the information spread evenly over
    the samples: their weights in the estimate `g_b = sum_(i in b) lam^age_i`
    and their score variances `v_b = sum_(i in b) lam^(2 age_i)` (per unit of
    information per sample), each `(seen + 1,)`."""
    size = jnp.asarray(size)
    partial = count % size
    full = count // size
    m = jnp.arange(seen)
    start = partial + m * size  # age of each full block's newest sample
    length = jnp.where(m < full, size, 0)
    start = jnp.concatenate([jnp.zeros(1, start.dtype), start])
    length = jnp.concatenate([partial[None], length])

    def geometric(r):
        if r == 1.0:
            return length.astype(float)
        return (
            jnp.power(r, start.astype(float))
            * (1.0 - jnp.power(r, length.astype(float)))
            / (1.0 - r)
        )

    return geometric(lam), geometric(lam**2)


def _centering_cross(lam, size, count):
    """How much more the estimate's error shares with each block's score than
    `K(V)` says (see [`_fitted_sandwich`][]), for blocks of `size` samples under
    the forgetting `lam` after `count` samples (the newest block partial), with
    the information spread evenly over the samples: `(sum_b g_b v_b / (sum g sum
    v)) / (sum_b g_b^2 / (sum g)^2)`, `g_b = sum_(i in b) lam^age_i` a block's
    weight in the estimate, `v_b = sum_(i in b) lam^(2 age_i)` its score's
    variance. 1 without forgetting (`g` proportional to `v`), above 1 with it:
    the newest blocks weigh more in the bound's variances than in the estimate
    (1.2-1.33 for blocks of a quarter of the memory, by where the newest block
    stands). Exact for independent blocks;
    summed in closed form over every block (geometric series in `lam^size`)."""
    if lam == 1.0:
        return jnp.ones(())
    size = jnp.asarray(size).astype(float)
    partial = (count % jnp.asarray(size).astype(int)).astype(float)
    full = (count // jnp.asarray(size).astype(int)).astype(float)
    log = np.log(lam)

    def one_less(x):  # 1 - lam^x, accurate for small x
        return -jnp.expm1(x * log)

    def series(q):  # sum over the full blocks m of lam^(q (partial + m size))
        return (
            jnp.exp(q * partial * log)
            * one_less(q * size * full)
            / jnp.maximum(one_less(q * size), 1e-300)
        )

    a, b = one_less(size) / (1 - lam), one_less(2 * size) / (1 - lam**2)
    g0, v0 = one_less(partial) / (1 - lam), one_less(2 * partial) / (1 - lam**2)
    sg, sv = g0 + a * series(1), v0 + b * series(2)
    sgv = g0 * v0 + a * b * series(3)
    sgg = g0**2 + a**2 * series(2)
    return (sgv / jnp.maximum(sg * sv, 1e-300)) / jnp.maximum(sgg / sg**2, 1e-300)


def _centering_loss(lam, size, count):
    """The degrees of freedom the bound loses to its residuals being taken at the
    estimate, for blocks of `size` samples under the forgetting `lam` after
    `count` samples (the newest block partial), with the information spread evenly
    over the samples.

    The block scores `U_b` are independent with variances `v_b = sum_(i in b)
    w_i^2` (times the information per sample), while the estimate weighs them by
    `g_b = sum_(i in b) w_i` ([`_block_geometry`][]); the bound sums the squares
    of `r = B U`, `B = I - g 1^T / sum g`. By Satterthwaite, that quadratic form
    has `nu = tr(B^T B S)^2 / tr((B^T B S)^2)` degrees of freedom, `S = diag(v)`;
    the returned loss is the effective number of blocks `(sum v)^2 / sum v^2`
    less `nu`. Without forgetting `g` is proportional to `v` and the loss is one
    block (the Student-t statistic); with forgetting the newest blocks dominate
    both the estimate and the bound, and centering costs less (0.15 at three
    effective blocks).
    """
    g, v = _block_geometry(lam, size, count)
    # (B^T B)_ij = delta_ij - (g_i + g_j) / G + sum g^2 / G^2, G = sum g, built
    # elementwise: a matrix product here, inside the replay's loop under vmap,
    # stalled XLA's CPU runtime
    total = jnp.maximum(g.sum(), 1e-300)
    btb = jnp.eye(len(g)) - (g[:, None] + g[None, :]) / total + jnp.sum(g**2) / total**2
    nu = jnp.sum(jnp.diag(btb) * v) ** 2 / jnp.maximum(
        jnp.sum(btb**2 * v[:, None] * v[None, :]), 1e-300
    )
    blocks = v.sum() ** 2 / jnp.maximum(jnp.sum(v**2), 1e-300)
    return blocks - nu


_EXTRAPOLATION = ((8, 1.0), (2, 0.25), (1, -0.25))  # V(b) + (V(b/4) - V(b/8)) / 4


def _extrapolated_share(lam, size, count):
    """The share of the effective number of blocks of `size` that the bound
    extrapolated over the block lengths, `V(b) + (V(b/4) - V(b/8)) / 4`, keeps as
    degrees of freedom: Satterthwaite's count of that quadratic form in the
    scores of the blocks of `size / 8` ([`_block_geometry`][]; the blocks of every
    length are counted from the first sample, so a block is a union of shorter
    ones), each level's bound centered at the estimate and divided by its
    expected share `1 - 2 sum_b g_b v_b / (sum g sum v) + sum_b g_b^2 / (sum
    g)^2` (the fitted sandwich's scale for evenly spread information), over the
    effective number of blocks of `size` (`(sum v)^2 / sum v^2`). Without
    forgetting, six blocks of equal length: 0.78 (the centering's one block
    and the extrapolation's noise); with a memory of four blocks 0.85."""
    fine = jnp.maximum(jnp.asarray(size) // _EXTRAPOLATION[0][0], 1)
    g, v = _block_geometry(lam, fine, count, seen=_EXTRAPOLATION[0][0] * _BLOCKS_SEEN)
    pos = count // fine - jnp.arange(len(g))  # the newest (partial) first
    total_g = jnp.maximum(g.sum(), 1e-300)
    total_v = jnp.maximum(v.sum(), 1e-300)
    # The form is A_ij = sum_k a_k (E_k,ij - (gs_k,i + gs_k,j) / G + share_k),
    # E_k the indicator of fine blocks i, j in the same group of grouping k and
    # gs_k,i the weight of i's group: a group-diagonal part B = sum_k a_k E_k
    # plus e_i + e_j. Its traces against S = diag(v) are sums over the groups
    # (segment sums, O(blocks)), not over the 513 x 513 pairs: the groupings
    # nest (a group of 2 lies in one of 8), so E_k E_l is the finer one's E.
    groups = [group for group, _ in _EXTRAPOLATION]
    nseg = len(g) // min(groups) + 2

    def group_sum(x, group):
        ids = pos // group - (pos[-1] // group)
        return jax.ops.segment_sum(x, ids, num_segments=nseg)[ids]

    a, e, diag = [], 0.0, 0.0
    for group, coef in _EXTRAPOLATION:
        g_group = group_sum(g, group)
        share = jnp.sum(g * g_group) / total_g**2
        scale = 1.0 - 2.0 * jnp.sum(g * group_sum(v, group)) / (total_g * total_v)
        scale = scale + share
        ak = coef / jnp.maximum(scale, 1e-300)
        a.append(ak)
        e = e + ak * (0.5 * share - g_group / total_g)
        diag = diag + ak
        if group == _EXTRAPOLATION[0][0]:
            blocks = total_v**2 / jnp.maximum(jnp.sum(v * group_sum(v, group)), 1e-300)
    trace = jnp.sum((diag + 2.0 * e) * v)
    # sum_ij B_ij^2 v_i v_j, sum_ij B_ij e_i v_i v_j, sum_ij (e_i + e_j)^2 v_i v_j
    bb = sum(
        a[k] * a[m] * jnp.sum(v * group_sum(v, min(groups[k], groups[m])))
        for k in range(len(groups))
        for m in range(len(groups))
    )
    be = sum(
        ak * jnp.sum(e * v * group_sum(v, grp))
        for ak, grp in zip(a, groups, strict=True)
    )
    ee = 2.0 * jnp.sum(e**2 * v) * jnp.sum(v) + 2.0 * jnp.sum(e * v) ** 2
    nu = trace**2 / jnp.maximum(bb + 4.0 * be + ee, 1e-300)
    return nu / blocks


_CRAIG = tuple(
    np.asarray(a) for a in np.polynomial.legendre.leggauss(12)
)  # Gauss-Legendre on (-1, 1), mapped to (0, pi / 2) in `_band_miss`


def _band_miss(crit, c):
    """The probability `(p,)` that `|Z| > crit sqrt(W)`, `Z` a standard normal and
    `W = sum_b c_b X_b / sum_b c_b` an independent weighted sum of one-degree
    chi-squares `X_b` (the shares `c` `(blocks, p)`, non-negative), and its
    derivative in `log crit`. Exact through Craig's form of the normal tail,
    `P(|Z| > x) = (2 / pi) int_0^(pi/2) exp(-x^2 / (2 sin^2 t)) dt`, whose
    expectation over `W` is the product of the chi-squares' Laplace transforms:
    `(2 / pi) int prod_b (1 + crit^2 c_b / (sum c sin^2 t))^(-1/2) dt`, smooth on
    a finite interval (12 Gauss-Legendre nodes: the critical values within 2e-7
    of 64 nodes' for equal, geometric and heavy-tailed shares)."""
    nodes, weights = _CRAIG
    t = (nodes + 1.0) * np.pi / 4.0
    sin2 = jnp.asarray(np.sin(t) ** 2)
    a = c / jnp.maximum(jnp.sum(c, axis=0, keepdims=True), 1e-300)  # (blocks, p)
    x = crit[None, None] ** 2 * a[None] / sin2[:, None, None]  # (nodes, blocks, p)
    prod = jnp.exp(-0.5 * jnp.sum(jnp.log1p(x), axis=1))  # (nodes, p)
    w = jnp.asarray(weights * np.pi / 4.0 * 2.0 / np.pi)[:, None]
    miss = jnp.sum(w * prod, axis=0)
    slope = -jnp.sum(w * prod * jnp.sum(x / (1.0 + x), axis=1), axis=0)
    return miss, slope


def _critical_value(c, start, level=0.95, iterations=3):
    """The critical value `(p,)` of a 95% band `theta +- crit * sqrt(bound)` when
    the bound is the weighted sum of one-degree chi-squares of [`_band_miss`][]
    (shares `c` `(blocks, p)`) and the error an independent normal: Newton's
    method on `log miss` against `log crit` from `start` `(p,)` (the Student-t
    quantile at Satterthwaite's count, near it: three steps reach the root
    within 1e-8)."""
    target = np.log(1.0 - level)

    def step(_, u):
        miss, slope = _band_miss(jnp.exp(u), c)
        miss = jnp.maximum(miss, 1e-300)
        u = u - (jnp.log(miss) - target) * miss / jnp.minimum(slope, -1e-300)
        return jnp.clip(u, np.log(1.959963984540054), np.log(100.0))

    return jnp.exp(jax.lax.fori_loop(0, iterations, step, jnp.log(start)))


def _t_dof(crit, z=1.959963984540054):
    """The degrees of freedom at which [`_t_quantile`][] is `crit` `(p,)`: its
    Cornish-Fisher polynomial in `x = 1 / dof`, increasing for `x > 0`, solved by
    Newton's method from `(crit - z) / A` (above the root: the polynomial's other
    terms are positive); `inf` at `crit <= z`."""
    a = (z**3 + z) / 4
    b = (5 * z**5 + 16 * z**3 + 3 * z) / 96
    c = (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384
    x0 = jnp.maximum(crit - z, 0.0) / a

    def step(_, x):
        f = a * x + b * x**2 + c * x**3 - (crit - z)
        return jnp.maximum(x - f / (a + 2 * b * x + 3 * c * x**2), 0.0)

    x = jax.lax.fori_loop(0, 20, step, x0)
    return 1.0 / jnp.maximum(x, 1e-300)


class RecursiveLeastSquares(AbstractRecursiveEstimator):
    """Recursive least squares with exponential forgetting, bounds corrected for
    coloured residuals by batch means over a ladder of block lengths (see the
    module docstring).

    **Fields:** `forgetting` (`lam`), `derivative` `(q,)` bool, `dt` (s),
    `levels`: the block lengths `1, 2, 4, ... 2^(levels - 1)` samples over which
    the scores are summed for the corrected bound (the longest should exceed the
    residuals' correlation time several times; the bound picks its block length
    from the data), `bandwidth` (Hz, optional): the low-pass of the differenced
    state equations.
    """

    forgetting: float = eqx.field(static=True)
    derivative: tuple[bool, ...] = eqx.field(static=True)
    dt: float = eqx.field(static=True)
    levels: int = eqx.field(static=True, default=12)
    bandwidth: float | None = eqx.field(static=True, default=None)

    def init(self, theta0, prior=1e6):
        p, q = len(theta0), len(self.derivative)
        return _empty_state(
            p, q, self.levels, np.zeros(0), self.dt, theta0, prior, True
        )

    def absorb(self, state, h, y):
        lam = self.forgetting
        p = h.shape[-1]
        active = jnp.any(h != 0, axis=1)
        # the running variance of the prediction errors (before this sample):
        # never the near-zero residual of a fit with fewer samples than parameters
        # each equation's residual variance over the memory, with the current
        # estimate (kept as sums of y^2, h y, h h^T: no early transient stays)
        th = state.theta
        ss = state.rows
        n = ss[:, 0, 0]
        rss = (
            ss[:, 0, 1]
            - 2.0 * ss[:, 1, 2:] @ th
            + jnp.einsum("a,qab,b->q", th, ss[:, 2:, 2:], th)
        )
        r = jnp.where(n > p + 1, jnp.maximum(rss, 0.0) / jnp.maximum(n, 1.0), jnp.nan)
        wq = _weights(r)
        # the rows of [1, y, h]^T [1, y, h] for those sums
        one = jnp.concatenate([active[:, None] * 1.0, y[:, None], h], axis=1)
        rows = lam * ss + jnp.einsum("qa,qb->qab", one, one)
        rows = rows.at[:, 0, 0].set(lam * n + active)
        hn, yn = h * wq[:, None], y * wq
        # the information form of recursive least squares: the same estimate as
        # the covariance form's gain update, without its loss of positive
        # definiteness when regressors are nearly collinear (a trim speed and an
        # intercept)
        info = lam * state.info + hn.T @ hn
        rhs = lam * state.rhs + hn.T @ yn
        theta = _solve(info, rhs)
        # the sample's score at any theta is a - G theta: z = [a, vec G] keeps
        # it exactly, so the bound is evaluated with the current estimate's
        # residuals (no transient of early estimates stays in it)
        z = jnp.concatenate([hn.T @ yn, (hn.T @ hn).reshape(p * p)])
        g = z[p:]
        # the block ladder: level j sums blocks of 2^j samples (forgetting-
        # weighted); a completed block's sum enters the pair sums and the
        # partial sums restart. The levels completing at a sample are a prefix
        # (those whose length divides the count), about two per sample: only
        # they are touched, their sums brought up to date by the forgetting
        # since they last were (`last`)
        size = 2 ** jnp.arange(self.levels)
        bz = lam * state.block_z + z[None]
        bg = lam**2 * state.block_g + g[None]
        done = ((state.count + 1) % size) == 0
        k = state.count

        def complete(j, carry):
            pairs, g2, g4, ring, ring_t, last = carry
            f = jnp.power(lam, (k - last[j]).astype(float))
            pairs = pairs.at[j].set(f**2 * pairs[j] + jnp.outer(bz[j], bz[j]))
            g2 = g2.at[j].set(f**2 * g2[j] + bg[j])
            g4 = g4.at[j].set(f**4 * g4[j] + jnp.outer(bg[j], bg[j]))
            slot = ((k + 1) // size[j]) % _RING
            ring = ring.at[j, slot].set(bg[j])
            ring_t = ring_t.at[j, slot].set(k)
            return pairs, g2, g4, ring, ring_t, last.at[j].set(k)

        sp = state.spread
        pairs, g2, g4, ring, ring_t, last = jax.lax.fori_loop(
            0,
            jnp.sum(done),
            complete,
            (state.pairs, sp.g2, sp.g4, sp.ring, sp.ring_t, state.block_t),
        )
        spread = _Spread(g2, g4, ring, ring_t)
        block_z = jnp.where(done[:, None], 0.0, bz)
        block_g = jnp.where(done[:, None], 0.0, bg)
        return eqx.tree_at(
            lambda s: (
                s.theta,
                s.info,
                s.rhs,
                s.r,
                s.rows,
                s.block_z,
                s.block_g,
                s.block_t,
                s.pairs,
                s.spread,
            ),
            state,
            (theta, info, rhs, r, rows, block_z, block_g, last, pairs, spread),
        )

    def _since(self, state):
        """Per level, the forgetting `lam^(k - block_t)` from when the level's
        sums were last brought up to date to the last sample absorbed, `k`."""
        age = jnp.maximum(state.count - 1 - state.block_t, 0)
        return jnp.power(self.forgetting, age.astype(float))

    def _blocks(self, state, pm):
        """The effective number of independent blocks `(levels, p)` behind each
        parameter's bound: the blocks' shares `c_b = (P C_b P)_aa` of the
        variance counted as `(sum c)^2 / sum c^2` (the partial blocks
        included)."""
        p = state.theta.shape[0]
        f2 = self._since(state)[:, None] ** 2
        g2 = f2 * state.spread.g2 + state.block_g
        g4 = f2[..., None] ** 2 * state.spread.g4 + jnp.einsum(
            "la,lb->lab", state.block_g, state.block_g
        )
        pp = jnp.einsum("ab,ac->abc", pm, pm).reshape(p, p * p)  # rows a: P_ab P_ac
        total = jnp.einsum("ak,lk->la", pp, g2)
        square = jnp.einsum("ai,lij,aj->la", pp, g4, pp)
        return total**2 / jnp.maximum(square, 1e-300)

    def _variance(self, state, pm, level):
        """The bound's variance `(p,)` from the block sums of one level (the
        partial block included), with the current estimate's scores `s = [I,
        -kron(I, theta^T)] z`."""
        p = state.theta.shape[0]
        bz = state.block_z[level]
        m = self._since(state)[level] ** 2 * state.pairs[level] + jnp.outer(bz, bz)
        t = jnp.concatenate([jnp.eye(p), -jnp.kron(jnp.eye(p), state.theta[None])], 1)
        cross = _centering_cross(self.forgetting, 2**level, state.count)
        return _fitted_sandwich(pm, t @ m @ t.T, m[p:, p:], p, cross)

    def ladder(self, state):
        """The bound at every block length: the variance `(levels, p)` and the
        effective number of blocks `(levels, p)` it rests on (for inspection;
        [`estimates`][] computes only the level it takes)."""
        pm = _inverse(state.info)
        var = jax.vmap(lambda j: self._variance(state, pm, j))(jnp.arange(self.levels))
        return var, self._blocks(state, pm)

    def estimates(self, state):
        pm = _inverse(state.info)
        blocks = self._blocks(state, pm)
        white = self._variance(state, pm, 0)
        white = jnp.where(white > 0, white, jnp.inf)
        # the longest blocks that leave at least three for every parameter (two
        # degrees of freedom): longer blocks leave less of the correlation out
        # (a block misses the correlation across its ends, a share falling as
        # one over its length), the Student-t quantile at their number less the
        # centering loss carries their fewness; fewer than three would leave
        # about one degree of freedom without forgetting, a band 6.5 times the
        # normal one
        usable = jnp.all(blocks >= 3.0, axis=1)
        j = jnp.max(jnp.where(usable, jnp.arange(self.levels), 0))
        var_c = self._variance(state, pm, j)
        # a block misses the correlation across its ends, a share falling as
        # one over its length: the bounds of the quarter and the eighth of the
        # length, V(b/4) - V(b/8) = 4 (V - V(b)) to that order, remove it
        # (Richardson's extrapolation in 1 / b over the ladder, from the
        # shorter blocks, which are many: their difference adds little noise),
        # whether the residuals' correlation is positive (coloured noise: the
        # bound was short) or negative (differenced noise, whose adjacent
        # blocks share the noise at their common end: the bound was long); its
        # own noise is in the degrees of freedom
        top = _EXTRAPOLATION[0][0]
        extrapolated = var_c
        for group, coef in _EXTRAPOLATION[1:]:
            lower = jnp.maximum(j - int(np.log2(top // group)), 0)
            extrapolated = extrapolated + coef * self._variance(state, pm, lower)
        extrapolate = (j >= int(np.log2(top))) & (extrapolated > 0)
        var_c = jnp.where(extrapolate, extrapolated, var_c)
        ok = jnp.any(usable) & (var_c > 0)
        var_c = jnp.where(ok, var_c, white)
        dof = jnp.where(
            extrapolate,
            blocks[j] * _extrapolated_share(self.forgetting, 2**j, state.count),
            blocks[j] - _centering_loss(self.forgetting, 2**j, state.count),
        )
        # Satterthwaite's count matches the bound's first two moments; where
        # the blocks weigh unequally (the newest under a memory, or the
        # manoeuvre's) the older ones make a floor that the two moments do not
        # see, and a Student-t band at the count is too wide. The count is
        # scaled by the degrees of freedom whose Student-t quantile is the exact
        # critical value of the blocks' own shares over their two-moment count
        # (1 for blocks of equal shares, to the Cornish-Fisher quantile's
        # accuracy: 0.987 at three blocks)
        dof = dof * self._tail_ratio(state, pm, j)
        dof = jnp.where(ok, jnp.maximum(dof, 1.0), 1.0)
        return _finish(state.theta, white, var_c, dof, student=True)

    def _shares(self, state, pm, level):
        """Each block's share `c_b = (P C_b P)_aa` `(ring + 1, p)` of the bound at
        one level: the newest `_RING` completed blocks (forgetting since they
        completed applied) and the partial one."""
        p = state.theta.shape[0]
        age = jnp.maximum(state.count - 1 - state.spread.ring_t[level], 0)
        f2 = jnp.power(self.forgetting, 2.0 * age.astype(float))
        cb = jnp.concatenate(
            [state.spread.ring[level] * f2[:, None], state.block_g[level][None]]
        )
        pp = jnp.einsum("ab,ac->abc", pm, pm).reshape(p, p * p)
        return jnp.maximum(cb @ pp.T, 0.0)

    def _tail_ratio(self, state, pm, level):
        """`(p,)`: the degrees of freedom of the exact critical value of a band
        whose bound is the blocks' shares times one-degree chi-squares
        ([`_critical_value`][]) over Satterthwaite's count of those shares,
        `(sum c)^2 / sum c^2`."""
        c = self._shares(state, pm, level)
        count = jnp.sum(c, 0) ** 2 / jnp.maximum(jnp.sum(c**2, 0), 1e-300)
        crit = _critical_value(c, _t_quantile(count))
        ratio = jnp.minimum(_t_dof(crit), 1e6) / jnp.maximum(count, 1e-300)
        return jnp.where(jnp.sum(c, 0) > 0, ratio, 1.0)


class RecursiveFourier(AbstractRecursiveEstimator):
    """Morelli's recursive Fourier transform equation error (see the module
    docstring).

    **Fields:** `frequencies` (Hz; e.g. 0.1 to 1.5 Hz every 0.04 Hz for aircraft
    rigid-body dynamics: the band of the manoeuvre, spaced at least `(1 - lam) / dt`
    apart so that the transforms stay independent), `forgetting` (default 1: the
    transforms span all the data), `derivative` `(q,)` bool, `dt` (s).
    """

    frequencies: tuple[float, ...] = eqx.field(static=True)
    forgetting: float = eqx.field(static=True)
    derivative: tuple[bool, ...] = eqx.field(static=True)
    dt: float = eqx.field(static=True)

    def __check_init__(self):
        if not self.frequencies or min(self.frequencies) <= 0:
            raise ValueError("frequencies must be positive (0 Hz carries the biases)")
        if max(self.frequencies) >= 0.5 / self.dt:
            raise ValueError(
                f"frequencies up to {max(self.frequencies):g} Hz reach the Nyquist "
                f"frequency {0.5 / self.dt:g} Hz of samples every {self.dt:g} s"
            )

    def init(self, theta0, prior=1e6):
        p, q = len(theta0), len(self.derivative)
        return _empty_state(p, q, 0, self.frequencies, self.dt, theta0, prior, False)

    def absorb(self, state, h, y):
        lam = self.forgetting
        ph = state.phasor * self.dt
        fh = lam * state.fh + ph[:, None, None] * h[None]
        fy = lam * state.fy + ph[:, None] * y[None]
        phasor = state.phasor * state.rotation
        phasor = phasor / jnp.abs(phasor)
        return eqx.tree_at(lambda s: (s.fh, s.fy, s.phasor), state, (fh, fy, phasor))

    def _end_terms(self, state, active):
        """`(f, q, 2 d)` the columns of the end terms of the `d` state equations,
        and `(2 d,)` which of them are used.

        A state equation's regressand is differenced, and its running transform
        telescopes: `sum_k lam^(K-k) z^k (x_k - x_(k-1)) = x_K z^K - lam^(K-1)
        z x_0 + sum_(0<k<K) x_k lam^(K-k-1) z^k (lam - z)`. The regressors'
        transforms carry the true state's ends; the measurement noise at the
        two ends (state units) enters the residuals through these two columns
        only: coherent across the frequencies (not the leakage of a locally flat
        spectrum the bound models), and at the lowest frequencies more power
        than the noise of the whole rest of the record, differenced (`|1 -
        z|^2` per sample). Both are estimated with the parameters, as the batch
        method estimates its end term `x(T) - x(0)`.
        Per equation the pair is orthogonalised (the second column dropped when
        it is nearly the first: at times when every frequency fits a whole
        number of cycles, and once the forgetting has erased the start).
        """
        rows = [i for i, d in enumerate(self.derivative) if d]
        f, q = state.fy.shape
        if not rows:
            return jnp.zeros((f, q, 0), state.fy.dtype), jnp.zeros(0, bool)
        last = state.phasor * jnp.conj(state.rotation)  # z^K, K = count - 1
        age = jnp.maximum(state.count - 2, 0).astype(float)
        first = -jnp.power(self.forgetting, age) * state.rotation  # -lam^(K-1) z
        norm = jnp.real(jnp.vdot(last, last))
        second = first - last * jnp.real(jnp.vdot(last, first)) / norm
        keep = jnp.real(jnp.vdot(second, second)) > 1e-8 * norm
        cols, used = [], []
        for i in rows:
            on = active[i] & (state.count >= 2)
            for c, k in ((last, on), (second, on & keep)):
                cols.append(jnp.zeros((f, q), c.dtype).at[:, i].set(c * k))
                used.append(k)
        return jnp.stack(cols, axis=-1), jnp.stack(used)

    def estimates(self, state):
        fh0, fy = state.fh, state.fy  # (f, q, p), (f, q)
        p0 = fh0.shape[-1]
        n_rows = jnp.sum(jnp.any(jnp.abs(fh0) > 0, axis=-1), axis=0)  # (q,)

        # which parameters the data move yet, judged without weights (a
        # noise-free equation's weight would dwarf every other column)
        plain = jnp.real(jnp.einsum("fqa,fqa->a", fh0.conj(), fh0))
        ends, used = self._end_terms(state, n_rows > 0)
        fh = jnp.concatenate([fh0, ends], axis=-1)  # (f, q, p): the end terms last
        p = fh.shape[-1]
        known = jnp.concatenate([plain > 1e-12 * jnp.max(plain), used])
        # complex degrees of freedom each equation's end terms take
        n_end = jnp.sum(jnp.any(jnp.abs(ends) > 0, axis=0), axis=-1)  # (q,)
        start = jnp.concatenate([state.theta, jnp.zeros(p - p0)])

        def solve(w):
            info = 2.0 * jnp.real(jnp.einsum("q,fqa,fqb->ab", w, fh.conj(), fh))
            rhs = 2.0 * jnp.real(jnp.einsum("q,fqa,fq->a", w, fh.conj(), fy))
            d = jnp.diag(info)
            scale = jnp.sqrt(jnp.maximum(d, 1e-300))
            cov = jnp.linalg.inv(
                info / jnp.outer(scale, scale) + jnp.diag(~known * 1.0)
            ) / jnp.outer(scale, scale)
            theta = jnp.where(known, cov @ rhs, start)
            e = fy - jnp.einsum("fqa,a->fq", fh, theta)
            power = jnp.sum(jnp.abs(e) ** 2, axis=0) / jnp.maximum(
                n_rows - 0.5 * p0 - 0.5 * n_end, 1.0
            )
            return theta, cov, known, e, power

        # equations weighted by their residual power (one pass to find it)
        _, _, _, _, power = solve(jnp.ones(fh.shape[1]))
        # relative weights, at most 1e8 apart (a noise-free equation)
        power = jnp.maximum(power, 1e-8 * jnp.max(power))
        w = jnp.where(n_rows > 0, 1.0 / jnp.maximum(power, 1e-300), 0.0)
        theta, cov, known, e, _ = solve(w)
        # the transforms of the equation errors at two frequencies are
        # correlated through the leakage of the finite (or forgetting-weighted)
        # transform: for residuals of a spectrum smooth over the kernel's
        # width, E[E_f E_g^H] = kappa_fg (S_f + S_g) / 2 with kappa the
        # normalised kernel `sum_i w_i^2 exp(-2 pi j (f - g) t_i) / sum_i
        # w_i^2` (1 on the diagonal)
        kappa = _leakage(
            jnp.asarray(self.frequencies), self.dt, self.forgetting, state.count
        )
        hw = w[None, :, None] * fh  # (f, q, p)
        pm = jnp.where(jnp.outer(known, known), cov, 0.0)
        var = jnp.where(known, jnp.clip(jnp.diag(cov), 0.0), jnp.inf)
        var_c, dof = _smooth_spectrum_bound(
            fh, hw, e, w, pm, kappa, jnp.asarray(self.frequencies), self.dt
        )
        var_c = jnp.where(known & (var_c > 0), var_c, var)
        return _finish(theta[:p0], var[:p0], var_c[:p0], dof[:p0], student=True)


def _hermitian_basis(q):
    """`(q * q, q, q)` complex: a real basis of the Hermitian `q x q` matrices."""
    out = []
    for i in range(q):
        for j in range(i, q):
            m = np.zeros((q, q), complex)
            if i == j:
                m[i, i] = 1.0
                out.append(m)
            else:
                m[i, j] = m[j, i] = 1.0
                out.append(m.copy())
                m[i, j], m[j, i] = 1j, -1j
                out.append(m)
    return np.stack(out)


def _nonnegative_least_squares(design, obs, free, iters=None):
    """`argmin |design c - obs|^2` with `c_i >= 0` where not `free`, by Lawson
    and Hanson's active set (the free coefficients always passive), and the
    `(k, rows)` linear map from `obs` to `c` on the final active set (the
    solution is that map times `obs`).

    `design` `(rows, k)`, `obs` `(rows,)`, `free` `(k,)` bool. A fixed number of
    passes (`3 k` by default) bounds the loop under `jit`."""
    k = design.shape[1]
    iters = 3 * k if iters is None else iters
    gram = design.T @ design
    rhs = design.T @ obs
    scale = jnp.sqrt(jnp.maximum(jnp.diag(gram), 1e-300))
    gram = gram / jnp.outer(scale, scale)
    rhs = rhs / scale
    # a relative ridge: the Bernstein columns of one equation are nearly
    # collinear, and an equation without rows has all-zero columns
    ridge = 1e-10 * jnp.max(jnp.diag(gram))

    def solve(passive):
        a = jnp.where(passive[:, None] & passive[None, :], gram, 0.0)
        a = a + jnp.diag(jnp.where(passive, ridge, 1.0))
        return jnp.linalg.solve(a, jnp.where(passive, rhs, 0.0)), a

    def inner(carry):
        x, passive, z, n = carry
        bad = passive & ~free & (z <= 0.0)
        step = jnp.min(jnp.where(bad, x / jnp.maximum(x - z, 1e-300), jnp.inf))
        x = x + jnp.clip(step, 0.0, 1.0) * (z - x)
        passive = passive & (free | (x > 1e-12 * jnp.max(jnp.abs(x))))
        x = jnp.where(passive, x, 0.0)
        z, _ = solve(passive)
        return x, passive, z, n + 1

    def outer(carry):
        x, passive, n = carry
        grad = jnp.where(passive, -jnp.inf, rhs - gram @ x)
        passive = passive.at[jnp.argmax(grad)].set(True)
        z, _ = solve(passive)
        x, passive, z, _ = jax.lax.while_loop(
            lambda c: jnp.any(c[1] & ~free & (c[2] <= 0.0)) & (c[3] < k),
            inner,
            (x, passive, z, 0),
        )
        return z, passive, n + 1

    def more(carry):
        x, passive, n = carry
        grad = rhs - gram @ x
        tol = 1e-10 * jnp.maximum(jnp.max(jnp.abs(rhs)), 1e-300)
        return jnp.any(~passive & (grad > tol)) & (n < iters)

    x0, _ = solve(free)
    x, passive, _ = jax.lax.while_loop(more, outer, (x0, free, 0))
    _, a = solve(passive)
    cols = jnp.where(passive[:, None], design.T / scale[:, None], 0.0)
    mapping = jnp.linalg.solve(a, cols) / scale[:, None]
    return mapping @ obs, mapping


def _smooth_spectrum_bound(fh, hw, e, w, pm, kappa, frequencies, dt):
    """The variance `(p,)` of the estimate and its Satterthwaite degrees of freedom
    `(p,)` from the residual spectrum estimated unbiased at the estimate.

    The equation errors' transforms `E_f` `(q,)` have the spectral covariance
    `S_f` `(q, q)`, across frequencies `E[E_f E_g^H] = kappa_fg (S_f + S_g) / 2`;
    the estimate's error is `delta = P 2 Re sum_g hw_g^H E_g`, its covariance
    `V(S) = P M(S) P`, `M(S) = Re sum_fg kappa_fg hw_f^H (S_f + S_g) hw_g`. The
    residuals at the estimate, `e_f = E_f - fh_f delta`, have

        E[e_f e_f^H] = S_f - fh_f D_f - D_f^H fh_f^H + fh_f V(S) fh_f^H,
        D_f = E[delta E_f^H] = P sum_g kappa_gf hw_g^H (S_g + S_f) / 2,

    linear in `S` (the hat matrix `H`'s `(I - H) S (I - H)^H` at frequency `f`,
    without taking the spectrum as flat). `S_f` is modelled as a quadratic in
    `|1 - z|^2 = 4 sin^2(pi f dt)` (Bernstein form) with Hermitian coefficients
    (white noise and differenced white noise are straight lines in it; a
    first-order lag's spectrum is smooth there), and the coefficients are the
    least squares fit of that expectation to the residual products `T_f = e_f
    e_f^H` (scaled by the local residual power) with each equation's own
    power non-negative at its three coefficients
    (`_nonnegative_least_squares`): for white and differenced white noise
    the truth lies inside that constraint, so the fit stays unbiased for
    them. Cross-spectra are not constrained: a fitted spectrum that is not
    positive semi-definite can still give a negative bound, which falls back
    to the white-residual one. The bound is a linear function of
    the `T_f`, `V_aa = sum_f Re tr(Q_f T_f)`: Satterthwaite's degrees of
    freedom are `2 (sum_f tr(Q_f S_f))^2 / sum_fg |kappa_fg|^2 tr(Q_f S_f Q_g
    S_g)` (each `T_f` a complex Gaussian's outer product)."""
    f, q, p = fh.shape
    # the quadratics in Bernstein form in the differenced white noise's own
    # shape, `|1 - z|^2 = 4 sin^2(pi f dt)`, 0 to 1 across the band: white
    # noise and differenced white noise are then straight lines with positive
    # ends, inside the non-negative coefficients the fit keeps, not on their
    # edge (in `f` a differenced noise's lowest coefficient is near zero)
    s = jnp.sin(jnp.pi * frequencies * dt) ** 2
    u = (s - s[0]) / jnp.maximum(s[-1] - s[0], 1e-300)
    prof = jnp.stack([(1.0 - u) ** 2, 2.0 * u * (1.0 - u), u * u])  # (k, f)
    herm_np = _hermitian_basis(q)
    herm = jnp.asarray(herm_np)  # (m, q, q)
    # each equation's own power non-negative at the three Bernstein
    # coefficients: a non-negative spectrum across the band
    diagonal = np.array(
        [
            np.trace(np.abs(b)) == 1
            and np.all(b.imag == 0)
            and np.count_nonzero(b) == 1
            for b in herm_np
        ]
    )
    free = jnp.asarray(np.tile(~diagonal, 3))
    a0 = jnp.einsum("fg,gqb->fqb", kappa, hw)  # sum_g kappa_fg hw_g
    ak = jnp.einsum("fg,kg,gqb->kfqb", kappa, prof, hw)  # ... times b_k(g)
    # M for S_f = b_k(f) E_m, (k, m, p, p)
    mm = jnp.real(
        jnp.einsum("kf,fqa,mqr,frb->kmab", prof, hw.conj(), herm, a0)
        + jnp.einsum("fqa,mqr,kfrb->kmab", hw.conj(), herm, ak)
    )
    vv = jnp.einsum("ab,kmbc,cd->kmad", pm, mm, pm)
    # D_f = P (ak_f^H + b_k(f) a0_f^H) E_m / 2, (k, m, f, p, q)
    lead = (
        jnp.conj(ak).transpose(0, 1, 3, 2)
        + prof[:, :, None, None] * jnp.conj(a0).transpose(0, 2, 1)[None]
    )  # (k, f, p, q)
    d = 0.5 * jnp.einsum("ab,kfbq,mqr->kmfar", pm, lead, herm)
    fd = jnp.einsum("fqa,kmfar->kmfqr", fh, d)
    pred = (
        prof[:, None, :, None, None] * herm[None, :, None]
        - fd
        - jnp.conj(fd).swapaxes(-1, -2)
        + jnp.einsum("fqa,kmab,frb->kmfqr", fh, vv.astype(fh.dtype), fh.conj())
    )
    t_f = jnp.einsum("fq,fr->fqr", e, e.conj())
    shapes = (prof[:, None, :, None, None] * herm[None, :, None]).reshape(-1, f, q, q)

    def fit(scale):
        design = (pred * scale[None, None]).reshape(-1, f * q * q)
        design = jnp.concatenate([design.real, design.imag], axis=1).T
        obs = (t_f * scale).reshape(-1)
        obs = jnp.concatenate([obs.real, obs.imag])
        coef, mapping = _nonnegative_least_squares(design, obs, free)
        return mapping, coef

    # first each equation scaled by its weight; then each frequency's products
    # by the first fit's spectrum there (generalised least squares: the
    # products' spread grows with the power, and the loud end of the band
    # must not set the quiet end's coefficients; weights from the whole fit
    # hardly depend on the product they weight)
    sw = jnp.sqrt(w)
    _, coef = fit(jnp.broadcast_to(sw[:, None] * sw[None, :], (f, q, q)))
    first = jnp.real(jnp.einsum("j,jfqq->fq", coef, shapes))
    first = jnp.maximum(first, 1e-3 * jnp.max(first, axis=0)[None] + 1e-300)
    sw = 1.0 / jnp.sqrt(first)
    scale = sw[:, :, None] * sw[:, None, :]  # (f, q, q)
    pinv, coef = fit(scale)
    cols = vv.reshape(-1, p, p)
    var_c = jnp.einsum("j,jaa->a", coef, cols)
    s_f = jnp.einsum("j,jfqr->fqr", coef, shapes)
    # V_aa = g_a . obs: back to Q_f with Re tr(Q_f T_f)
    g = jnp.einsum("jr,ja->ar", pinv, jnp.einsum("jaa->ja", cols))  # (p, rows)
    half = f * q * q
    gc = (g[:, :half] + 1j * g[:, half:]).reshape(p, f, q, q)
    qf = jnp.conj(gc) * scale[None]  # Re sum_ij conj(G_ij) T_ij scale_ij = Re tr(Q T)
    qf = 0.5 * (qf.swapaxes(-1, -2) + jnp.conj(qf))  # Q with Re tr(Q T): Hermitian
    r = jnp.einsum("afij,fjk->afik", qf, s_f)
    mean = jnp.real(jnp.einsum("afii->a", r))
    spread = jnp.real(jnp.einsum("fg,afij,agji->a", jnp.abs(kappa) ** 2, r, r))
    dof = jnp.where(
        (mean > 0) & (spread > 0), 2.0 * mean**2 / jnp.maximum(spread, 1e-300), 1.0
    )
    return var_c, dof


def _leakage(frequencies, dt, forgetting, count):
    """`(f, f)` complex: the correlation `sum_i w_i^2 z^i / sum_i w_i^2`, `z =
    exp(-2 pi j (f - g) dt)`, of the running transforms at two frequencies of a
    white signal, `w_i = lam^(count - 1 - i)` over the `count` samples absorbed."""
    n = jnp.maximum(count, 1).astype(float)
    diff = frequencies[:, None] - frequencies[None, :]
    z = jnp.exp(-2j * jnp.pi * diff * dt)
    zn = jnp.exp(-2j * jnp.pi * diff * dt * n)
    lam2 = forgetting**2
    same = jnp.abs(diff) < 1e-12
    safe = jnp.where(same, 0.5, z)
    if forgetting == 1.0:
        total = n
        num = (1.0 - zn) / (1.0 - safe)
    else:
        total = (1.0 - lam2**n) / (1.0 - lam2)
        num = (lam2**n - zn) / (lam2 - safe)
    return jnp.where(same, 1.0, num / total)


class RecursiveHistory(eqx.Module):
    """Estimates over a replay: `t` `(n,)` s (every sample, or the samples asked
    for), `theta`, `stderr`, `stderr_corrected`, `halfwidth` (of the 95% band),
    `dof` `(n, p)` (see [`RecursiveEstimates`][])."""

    t: Float[Array, " n"]
    theta: Float[Array, "n p"]
    stderr: Float[Array, "n p"]
    stderr_corrected: Float[Array, "n p"]
    halfwidth: Float[Array, "n p"]
    dof: Float[Array, "n p"]


@eqx.filter_jit
def replay(
    estimator: AbstractRecursiveEstimator,
    h: Float[Array, "n q p"],
    y: Float[Array, "n q"],
    o: Float[Array, "n q"],
    theta0: Float[Array, " p"],
    t0: float = 0.0,
    prior: float = 1e6,
    at: tuple[int, ...] | None = None,
) -> RecursiveHistory:
    """Run `estimator` over a record's regression, sample by sample (one compiled
    `lax.scan` of `update`), and keep the estimates after every sample, or only
    after the samples `at`.

    **Arguments:** the regression `h` `(n, q, p)`, `y`, `o` `(n, q)` (see the module
    docstring and [`model_regression`][]), the start `theta0` `(p,)`, the first
    sample's time `t0` (s), the prior variance, `at`: increasing sample indices
    (0-based) after which the estimates are wanted (`None`: every sample). With
    `at`, only the updates run between them (the estimates' bound is most of the
    cost of a sample), so a Monte Carlo `vmap`s cheaply over flights.

    **Returns:** a [`RecursiveHistory`][].
    """
    state = estimator.init(theta0, prior)
    n = h.shape[0]

    def unpack(est):
        return (est.theta, est.stderr, est.stderr_corrected, est.halfwidth, est.dof)

    if at is None:

        def step(state, sample):
            state = estimator.update(state, *sample)
            return state, unpack(estimator.estimates(state))

        _, out = jax.lax.scan(step, state, (h, y, o))
        t = t0 + jnp.arange(n) * estimator.dt
        return RecursiveHistory(t, *out)

    idx = [int(k) for k in at]
    if any(b <= a for a, b in zip(idx, idx[1:], strict=False)) or not (
        0 <= idx[0] and idx[-1] < n
    ):
        raise ValueError(
            f"`at` must be increasing sample indices in [0, {n}), got {at}"
        )

    def only(state, sample):
        return estimator.update(state, *sample), None

    outs, begin = [], 0
    for k in idx:
        state, _ = jax.lax.scan(
            only, state, (h[begin : k + 1], y[begin : k + 1], o[begin : k + 1])
        )
        outs.append(unpack(estimator.estimates(state)))
        begin = k + 1
    out = [jnp.stack(parts) for parts in zip(*outs, strict=True)]
    t = t0 + jnp.asarray(idx, float) * estimator.dt
    return RecursiveHistory(t, *out)


class Regression(eqx.Module):
    """A model's equation-error regression over a record, for the recursive
    estimators: `h` `(n, q, p)`, `y`, `o` `(n, q)`, `derivative` `(q,)`, the names of
    the equations and of the `p` parameters (the model's estimable ones), and
    `index` `(p,)` their positions in the model's parameters."""

    h: Float[Array, "n q p"]
    y: Float[Array, "n q"]
    o: Float[Array, "n q"]
    derivative: tuple[bool, ...] = eqx.field(static=True)
    equations: tuple[str, ...] = eqx.field(static=True)
    parameters: tuple[str, ...] = eqx.field(static=True)
    index: tuple[int, ...] = eqx.field(static=True)
    mask: Bool[Array, " q"] | None = None


def model_regression(model, record) -> Regression:
    """The equation-error regression of a [`Model`][] on a [`Record`][]: a state
    equation for every state measured (an output of the same name; a derivative
    row) and an output equation for every output a free parameter enters that is
    not itself a state, with the measured states in place of the model's. The model
    must be linear (affine) in its free parameters in these equations; the
    parameters no equation contains are left out.

    **Returns:** a [`Regression`][] whose `p` parameters are the estimable ones.
    """
    record.check(model)
    nx = len(model.states)
    xs = record.measured_states(model, np.arange(len(record.t)))
    measured = ~np.isnan(xs[0])
    xs = np.nan_to_num(xs)
    start = np.asarray(model.start, float)
    free = np.asarray(model.free)

    def equations(theta, t, x, u):
        return jnp.concatenate([model.f(t, x, u, theta), model.g(t, x, u, theta)])

    def at(theta):
        return jax.vmap(equations, (None, 0, 0, 0))(
            theta, jnp.asarray(record.t), jnp.asarray(xs), jnp.asarray(record.inputs)
        )

    jac_fn = jax.jit(lambda th: (at(th), jax.jacfwd(at)(th)))
    values, jac = (np.asarray(a) for a in jac_fn(jnp.asarray(start)))
    step = 0.3 * np.maximum(np.abs(start), 1.0) * free
    _, jac2 = (np.asarray(a) for a in jac_fn(jnp.asarray(start + step)))
    rows = [i for i in range(nx) if measured[i]]
    rows += [
        nx + j
        for j, name in enumerate(model.outputs)
        if name not in model.states and np.any(jac[:, nx + j][:, free] != 0)
    ]
    jac, jac2, values = jac[:, rows], jac2[:, rows], values[:, rows]
    nonlinear = np.abs(jac - jac2)[..., free].max(axis=(0, 1)) > 1e-7 * np.maximum(
        np.abs(jac)[..., free].max(axis=(0, 1)), 1e-300
    )
    if nonlinear.any():
        name = np.asarray(model.parameters)[free][int(np.argmax(nonlinear))]
        raise ValueError(
            f"the model's equations are not linear in the parameter {name!r}: "
            "recursive equation error solves a least-squares problem; write the "
            "model with it entering linearly, or hold it (fixed=...)"
        )
    used = free & np.any(jac != 0, axis=(0, 1))
    if not used.any():
        raise ValueError("no free parameter enters the model's equations")
    index = np.flatnonzero(used)
    h = jac[..., index]
    offset = values - h @ start[index]
    names = [model.states[i] for i in range(nx) if measured[i]]
    names += [f"{model.outputs[r - nx]}" for r in rows[len(names) :]]
    y = np.column_stack(
        [xs[:, r] if r < nx else record.measured[:, r - nx] for r in rows]
    )
    derivative = tuple(r < nx for r in rows)
    return Regression(
        h=jnp.asarray(h),
        y=jnp.asarray(y),
        o=jnp.asarray(offset),
        derivative=derivative,
        equations=tuple(
            f"d{n}/dt" if d else n for n, d in zip(names, derivative, strict=True)
        ),
        parameters=tuple(model.parameters[i] for i in index),
        index=tuple(int(i) for i in index),
    )


COEFFICIENT_PARAMETERS = (
    "CL0", "CLa", "CLde", "CD0", "CDa", "CDde", "CM0", "CMa", "CMde",
)  # fmt: skip


def coefficient_regression(channels: dict, s_ref: float, c_ref: float) -> Regression:
    """The launch vehicle's regression: `CL, CD, CM` reconstructed from the
    measured channels ([`reconstruct_coefficients`][]) each on `[1, alpha, de]`
    (1/rad): three equations, nine parameters ([`COEFFICIENT_PARAMETERS`][]); the
    intercepts carry the trim and the untracked terms."""
    from ._coefficients import reconstruct_coefficients

    coeffs = reconstruct_coefficients(
        {k: jnp.asarray(v) for k, v in channels.items()}, s_ref, c_ref
    )
    alpha, de = jnp.asarray(channels["alpha"]), jnp.asarray(channels["de"])
    row = jnp.stack([jnp.ones_like(alpha), alpha, de], axis=-1)  # (n, 3)
    n = row.shape[0]
    h = jnp.zeros((n, 3, 9))
    for j in range(3):
        h = h.at[:, j, 3 * j : 3 * j + 3].set(row)
    y = jnp.stack([coeffs.CL, coeffs.CD, coeffs.CM], axis=-1)
    return Regression(
        h=h,
        y=y,
        o=jnp.zeros_like(y),
        derivative=(False, False, False),
        equations=("CL", "CD", "CM"),
        parameters=COEFFICIENT_PARAMETERS,
        index=tuple(range(9)),
    )


def forgetting_for(memory: float, dt: float) -> float:
    """The forgetting factor whose memory (time constant) is `memory` seconds at
    samples every `dt` seconds: `exp(-dt / memory)`; 1 for an infinite memory."""
    if memory is None or not np.isfinite(memory):
        return 1.0
    if not memory > 0:
        raise ValueError(f"memory must be positive seconds, got {memory}")
    return float(np.exp(-dt / memory))
