/* Stage-structured QP: Riccati recursion inside a warm-started dual active-set method, and
 * an interior-point method on the same kernels (stage_qp_ipm, at the end).
 *
 * Solves   min  sum_j 1/2 z_j' H_j z_j + q_j' z_j,   z_j = (x_j, u_j), z_N = x_N
 *          s.t. x_{j+1} = AB_j z_j + b_j            (j = 0..N-1; x_0 is free)
 *               C x_N = d                           (nc terminal equalities)
 *               lb <= z <= ub                       (entries may be +-INFINITY)
 *
 * Every iterate is the solution of an equality-constrained QP (EQP) in which the bounds of
 * the active set are fixed. Each EQP is one Riccati factorisation; the fixed bounds and
 * C x_N = d enter through an augmented Lagrangian with weight rho, whose multipliers are
 * updated by cheap backward/forward vector passes until the equalities hold to eq_tol.
 * The recursion runs backward, so a change of the active set at stage k leaves the factors
 * of stages k+1..N as they were: only stages k..0 are redone (unless reuse is 0).
 *
 * 1. The caller's guess of the active set (act: -1 lower, +1 upper, 0 free; the previous
 *    sampling instant's) is made dual feasible by releasing bounds whose multiplier has the
 *    wrong sign. Usually this is a single EQP, and the answer.
 * 2. Then dual active-set steps (Goldfarb & Idnani, 1983): the most violated bound is moved
 *    from its current value to the bound; solution and multipliers are affine along the way,
 *    and a fixed bound whose multiplier reaches zero first is released there (a partial
 *    step). A bound that depends on the fixed ones gets a pure dual step along the
 *    direction in which the inconsistent EQP's multipliers diverge. Each step keeps dual
 *    feasibility, so the method terminates for a strictly convex QP.
 *
 * Storage: matrices column-major; blocks of all stages concatenated.  H_j is s_j x s_j with
 * s_j = nx_j + nu_j; AB_j is nx_{j+1} x s_j; C is nc x nx_N.
 *
 * Speed: the stages are a few dozen numbers wide, where loops cost more than arithmetic.
 * Each stage's work is one kernel written for sizes (x, u, x1) = (nx_j, nu_j, nx_{j+1});
 * compiled with -DSQP_NX=a -DSQP_NU=b, the kernels are also instantiated for the constant
 * sizes (a, b, a), which stages of those sizes use: fixed trip counts let the compiler
 * vectorise and unroll them and keep their sums in registers (about 3x on the crossing's
 * QPs, a = 18, b = 4). Both instances do the same operations in the same order, so they give
 * the same numbers; the generic one serves all other stages. Every sum also runs over the
 * same terms in the same order as in the plain loops this replaced (dot products over the
 * nonzeros of AB): with unfused multiply-adds both give the same bits.
 *
 * Return: 0 solved; 1 max_outer EQPs used; 2 infeasible (or an EQP that could not be made
 * consistent); 3 a factorisation was not positive definite; 4 workspace too small.
 */
#include <math.h>
#include <string.h>

/* The stage kernels are inlined into a generic and a fixed-size instance each (INSTANCE). */
#define KERNEL static inline __attribute__((always_inline))
/* Loops over a stage's rows, fully unrolled where the size is a constant: the compiler then
 * keeps the accumulators in registers, not in memory (a store and a reload in every step of
 * a chain of multiply-adds); 1.3x on the crossing's QPs. */
#define UNROLL _Pragma("GCC unroll 32")
#define INSTANCE static __attribute__((noinline))
/* A loop whose arrays do not overlap (see stage_qp_ipm). */
#define IVDEP _Pragma("GCC ivdep")

/* Multiply-adds are fused explicitly. Left to itself the compiler fuses a*b + c in some
 * loops and not in others (not in sums it vectorises in order, nor in some masked vector
 * remainders), and decides differently for the generic and the fixed-size instances: their
 * results would differ in the last bits. (-D'FMA(a,b,c)=((a)*(b)+(c))'
 * with -ffp-contract=off gives the unfused arithmetic, for comparisons.) */
#ifndef FMA
#define FMA(a, b, c) fma(a, b, c)
#endif

typedef struct {
    int outer;    /* active-set iterations used */
    int passes;   /* vector passes (multiplier updates) in all */
    int changes;  /* active-set changes in all */
    int n_active; /* active bounds at the solution */
    int stages;   /* stage factorisations in all (N + 1 per full factorisation) */
} qp_stats;

static int off_w(const int *nx, const int *nu, int j) {
    int o = 0;
    for (int i = 0; i < j; ++i) o += nx[i] + nu[i];
    return o;
}

/* In-place Cholesky of the leading n x n block (stride ld); lower triangle. */
KERNEL int chol(double *a, int n, int ld) {
    for (int k = 0; k < n; ++k) {
        double d = a[k + k * ld];
        for (int i = 0; i < k; ++i) d = FMA(-a[k + i * ld], a[k + i * ld], d);
        if (!(d > 0.0)) return 1;
        d = sqrt(d);
        a[k + k * ld] = d;
        for (int r = k + 1; r < n; ++r) {
            double s = a[r + k * ld];
            for (int i = 0; i < k; ++i) s = FMA(-a[r + i * ld], a[k + i * ld], s);
            a[r + k * ld] = s / d;
        }
    }
    return 0;
}

/* Solve L L' v = v in place (L lower, stride ld). */
KERNEL void chol_solve(const double *l, int n, int ld, double *v) {
    for (int k = 0; k < n; ++k) {
        double s = v[k];
        for (int i = 0; i < k; ++i) s = FMA(-l[k + i * ld], v[i], s);
        v[k] = s / l[k + k * ld];
    }
    for (int k = n - 1; k >= 0; --k) {
        double s = v[k];
        for (int i = k + 1; i < n; ++i) s = FMA(-l[i + k * ld], v[i], s);
        v[k] = s / l[k + k * ld];
    }
}

static size_t nz_ints(int n, const int *nx, const int *nu);

size_t stage_qp_workspace(int n, const int *nx, const int *nu, int nc) {
    size_t w = 0, nw = 0;
    int mx = 0;
    for (int j = 0; j <= n; ++j) {
        int s = nx[j] + (j < n ? nu[j] : 0);
        w += (size_t)nx[j] * nx[j] + (size_t)s * s;  /* P_j, M_j */
        nw += s;
        mx = nx[j] > mx ? nx[j] : mx;
    }
    /* g, pv, dg, target, z0, lam0, dlam; C'C; lamc0, dlamc; AB' (as many entries as AB); the
     * nonzero lists of the AB columns (ints: one row index per entry of AB_j, one count per
     * column), in doubles; the active set of the current factors (chars) */
    size_t nab = 0;
    for (int j = 0; j < n; ++j) nab += (size_t)nx[j + 1] * (nx[j] + nu[j]);
    return w + 7 * nw + (size_t)nx[n] * nx[n] + 2 * (size_t)nc + nab
           + (nz_ints(n, nx, nu) + 1) / 2 + (nw + sizeof(double) - 1) / sizeof(double);
}

/* Entries of the nonzero lists: rows of every AB_j column, then a count per column. */
static size_t nz_ints(int n, const int *nx, const int *nu) {
    size_t k = 0;
    for (int j = 0; j < n; ++j) k += (size_t)(nx[j + 1] + 1) * (nx[j] + nu[j]);
    return k;
}

/* The rows of the nonzero entries of every column of AB_j (idx, x1 slots per column) and
 * their number (cnt). About two thirds of AB is structurally zero here (the carried
 * equilibrium and barrier states), and the products below run over the nonzeros only, in
 * the same order as a dense loop: skipped terms are exact zeros, so results are unchanged.
 * Also AB_j' (abt, s x x1), for the vector passes. */
static void nonzeros(int n, const int *nx, const int *nu, const double *ab, int *idx,
                     int *cnt, double *abt) {
    for (int j = 0; j < n; ++j) {
        int s = nx[j] + nu[j], x1 = nx[j + 1];
        for (int cc = 0; cc < s; ++cc, ab += x1, idx += x1) {
            int m = 0;
            for (int k = 0; k < x1; ++k) {
                abt[cc + k * s] = ab[k];
                if (ab[k] != 0.0) idx[m++] = k;
            }
            *cnt++ = m;
        }
        abt += (size_t)s * x1;
    }
}

typedef struct {
    int n, nc, nw, max_passes;
    const int *nx, *nu, *idx, *cnt;  /* idx, cnt: nonzero lists of the AB columns */
    const double *h, *q, *ab, *b, *c, *d;
    double rho, eq_tol;
    double **P, **M, *g, *pv, *ctc;  /* ctc: C'C */
    double *dg;                      /* the diagonal added to H (see factorise) */
    double *abt;                     /* AB_j' */
    double *dlam, *dlamc;  /* last multiplier update: the dual direction when inconsistent */
    signed char *fact_act; /* the active set of the current factors, */
    int fact_valid;        /* if any (not at the start of a call, nor after a failed one) */
    int reuse;             /* 0: refactorise every stage every time (a check of the reuse) */
    /* Offsets of stage j's blocks, computed once per solve rather than summed over the
     * stages below at every use (that was O(N^2) per factorisation and per pass). */
    const size_t *oz, *oh, *oab, *ob;  /* z_j (and cnt_j), H_j, AB_j (and idx_j), b_j */
} problem;

/* ---- Stage kernels: sizes x = nx_j, u = nu_j, x1 = nx_{j+1}, s = x + u. ----
 * M_j holds, after factor_stage: L_uu (Cholesky factor of the input block) in its lower
 * (u, u) block, K_j' (x by u, K_j = -M_uu^{-1} M_ux) in its upper right block, M_ux in its
 * lower left one. K is kept transposed so that every use runs along a contiguous column of
 * length x, which vectorises. */

/* out = AB' B by rows: row c of out (w entries) sums AB_kc B_k over the nonzeros k of AB's
 * column c (B by rows of w entries: P_{j+1}, symmetric, or the terminal terms' Pi_{j+1});
 * acc holds w sums. */
KERNEL void columns_times(const int w, const int s, const int x1, const double *restrict a,
                          const int *restrict ix, const int *restrict cn,
                          const double *restrict b, double *restrict acc,
                          double *restrict out) {
    for (int cc = 0; cc < s; ++cc) {
        UNROLL for (int r = 0; r < w; ++r) acc[r] = 0.0;
        const double *acol = a + (size_t)cc * x1;
        const int *ic = ix + (size_t)cc * x1;
        for (int i = 0; i < cn[cc]; ++i) {
            int k = ic[i];
            double v = acol[k];
            const double *bk = b + (size_t)k * w;
            UNROLL for (int r = 0; r < w; ++r) acc[r] = FMA(bk[r], v, acc[r]);
        }
        UNROLL for (int r = 0; r < w; ++r) out[r + cc * w] = acc[r];
    }
}

/* M_j = H_j + diag(dg_j) + AB' P_{j+1} AB, its Cholesky/K, and P_j. dg_j is the
 * augmented-Lagrangian weight on the fixed bounds (active-set method) or the barrier's
 * curvature (interior point). */
KERNEL int factor_stage(const int x, const int u, const int x1, const double *restrict h,
                        const double *restrict dg,
                        const double *restrict a, const int *restrict ix,
                        const int *restrict cn, const double *restrict p1,
                        double *restrict m, double *restrict p, double *restrict t,
                        double *restrict tc,
                        double *restrict tt, double *restrict acc, double *restrict kt,
                        double *restrict col) {
    const int s = x + u;
    /* tt = (P_{j+1} AB)', column k being row k of P AB: the next product then takes whole
     * contiguous rows of it. Each column of P AB sums over the nonzeros of AB's column. */
    columns_times(x1, s, x1, a, ix, cn, p1, t, tc);
    /* The transpose as a pass of its own: stored across (stride s) in the loop above, t
     * would be split into scalars, and its sums done one number at a time. */
    for (int k = 0; k < x1; ++k)
        for (int cc = 0; cc < s; ++cc) tt[cc + k * s] = tc[k + cc * x1];
    /* Column r of AB' (P AB) = sum over the nonzeros AB_kr of AB_kr tt[:, k]: element c is
     * the dot product of AB[:, r] with column c of P AB, summed in the same order as the
     * dot product would be, but along c, which vectorises. Entries c <= r are kept (upper
     * triangle), the rest mirrored from them, so M is exactly symmetric. */
    for (int r = 0; r < s; ++r) {
        UNROLL for (int c = 0; c < s; ++c) acc[c] = 0.0;
        const double *ar = a + (size_t)r * x1;
        const int *ir = ix + (size_t)r * x1;
        for (int i = 0; i < cn[r]; ++i) {
            int k = ir[i];
            double v = ar[k];
            const double *tk = tt + k * s;
            UNROLL for (int c = 0; c < s; ++c) acc[c] = FMA(tk[c], v, acc[c]);
        }
        /* the whole column, of constant length (acc stays in registers); the entries below
         * the diagonal are overwritten by the mirror */
        const double *hr = h + (size_t)r * s;
        double *mr = m + (size_t)r * s;
        UNROLL for (int c = 0; c < s; ++c) mr[c] = hr[c];
        mr[r] += dg[r];
        UNROLL for (int c = 0; c < s; ++c) mr[c] += acc[c];
    }
    for (int cc = 0; cc < s; ++cc)
        for (int r = cc + 1; r < s; ++r) m[r + cc * s] = m[cc + r * s];
    /* Input block: Cholesky; K' = -M_xu M_uu^{-1}, the substitutions of chol_solve done for
     * all x rows at once (same operations per row, in the same order). */
    if (u > 0) {
        double *l = m + x + (size_t)x * s;
        if (chol(l, u, s)) return 3;
        /* kt: a private copy, which does not alias l, so the loops vectorise */
        for (int i = 0; i < u; ++i)
            for (int r = 0; r < x; ++r) kt[r + i * x] = m[r + (size_t)(x + i) * s];
        for (int k = 0; k < u; ++k) {
            double *vk = kt + k * x;
            for (int i = 0; i < k; ++i) {
                double c = l[k + i * s];
                const double *vi = kt + i * x;
                UNROLL for (int r = 0; r < x; ++r) vk[r] = FMA(-c, vi[r], vk[r]);
            }
            double dk = l[k + k * s];
            UNROLL for (int r = 0; r < x; ++r) vk[r] = vk[r] / dk;
        }
        for (int k = u - 1; k >= 0; --k) {
            double *vk = kt + k * x;
            for (int i = k + 1; i < u; ++i) {
                double c = l[i + k * s];
                const double *vi = kt + i * x;
                UNROLL for (int r = 0; r < x; ++r) vk[r] = FMA(-c, vi[r], vk[r]);
            }
            double dk = l[k + k * s];
            UNROLL for (int r = 0; r < x; ++r) vk[r] = vk[r] / dk;
        }
        for (int i = 0; i < u; ++i)
            for (int r = 0; r < x; ++r) m[r + (size_t)(x + i) * s] = -kt[r + i * x];
    }
    /* P_j = M_xx + K' M_ux, column by column (along r, which vectorises); then the mean of
     * it and its transpose, exactly symmetric. */
    const double *ktm = m + (size_t)x * s;
    for (int cc = 0; cc < x; ++cc) {
        UNROLL for (int r = 0; r < x; ++r) col[r] = m[r + (size_t)cc * s];
        for (int i = 0; i < u; ++i) {
            double v = m[x + i + (size_t)cc * s];
            const double *ki = ktm + (size_t)i * s;
            UNROLL for (int r = 0; r < x; ++r) col[r] = FMA(ki[r], v, col[r]);
        }
        UNROLL for (int r = 0; r < x; ++r) p[r + cc * x] = col[r];
    }
    for (int cc = 0; cc < x; ++cc)
        for (int r = cc + 1; r < x; ++r) {
            double v = 0.5 * (p[r + cc * x] + p[cc + r * x]);
            p[r + cc * x] = p[cc + r * x] = v;
        }
    return 0;
}

/* Backward pass of stage j: pv holds p_{j+1} on entry, p_j on return; mv (stage j's slots
 * of z) gets m_j's x part and k_j = -M_uu^{-1} m_u. */
KERNEL void back_stage(const int x, const int u, const int x1, const double *restrict abt,
                       const double *restrict bj, const double *restrict gj,
                       const double *restrict p1, const double *restrict m,
                       double *restrict pv, double *restrict mv, double *restrict w,
                       double *restrict mu, double *restrict pj, double *restrict ml) {
    const int s = x + u;
    /* w = P_{j+1} b_j + p_{j+1} */
    UNROLL for (int r = 0; r < x1; ++r) w[r] = pv[r];
    for (int k = 0; k < x1; ++k) {
        double v = bj[k];
        if (v == 0.0) continue;
        UNROLL for (int r = 0; r < x1; ++r) w[r] = FMA(p1[r + (size_t)k * x1], v, w[r]);
    }
    /* m = g_j + AB' w, as a sum of the columns of AB' (rows of AB) along s, which
     * vectorises: per entry the terms and their order are those of the dot product over the
     * nonzeros of AB's column (a zero term changes nothing). */
    UNROLL for (int r = 0; r < s; ++r) ml[r] = gj[r];
    for (int k = 0; k < x1; ++k) {
        double v = w[k];
        const double *ak = abt + (size_t)k * s;
        UNROLL for (int r = 0; r < s; ++r) ml[r] = FMA(ak[r], v, ml[r]);
    }
    /* p_j = m_x + K' m_u (along x); k_j = -M_uu^{-1} m_u (kept in mv's u slots) */
    for (int i = 0; i < u; ++i) mu[i] = ml[x + i];
    const double *kt = m + (size_t)x * s;
    UNROLL for (int r = 0; r < x; ++r) pj[r] = ml[r];
    for (int i = 0; i < u; ++i)
        UNROLL for (int r = 0; r < x; ++r) pj[r] = FMA(kt[r + (size_t)i * s], mu[i], pj[r]);
    UNROLL for (int r = 0; r < x; ++r) pv[r] = pj[r];
    if (u > 0) {
        chol_solve(m + x + (size_t)x * s, u, s, mu);
        for (int i = 0; i < u; ++i) mv[x + i] = -mu[i];
    }
}

/* Forward pass of stage j: u_j = K_j x_j + k_j, then x_{j+1} = AB_j z_j + b_j into zj + s. */
KERNEL void fwd_stage(const int x, const int u, const int x1, const double *restrict a,
                      const double *restrict bj, const double *restrict m,
                      double *restrict zj, double *restrict acc, double *restrict zn) {
    const int s = x + u;
    const double *kt = m + (size_t)x * s;
    /* the u sums side by side (each in its own order), not one after the other */
    UNROLL for (int i = 0; i < u; ++i) acc[i] = zj[x + i];  /* k_j */
    for (int r = 0; r < x; ++r)
        UNROLL for (int i = 0; i < u; ++i) acc[i] = FMA(kt[r + (size_t)i * s], zj[r], acc[i]);
    UNROLL for (int i = 0; i < u; ++i) zj[x + i] = acc[i];
    UNROLL for (int r = 0; r < x1; ++r) zn[r] = bj[r];
    for (int cc = 0; cc < s; ++cc) {
        double v = zj[cc];
        if (v == 0.0) continue;
        const double *acol = a + (size_t)cc * x1;
        UNROLL for (int r = 0; r < x1; ++r) zn[r] = FMA(acol[r], v, zn[r]);
    }
    UNROLL for (int r = 0; r < x1; ++r) zj[s + r] = zn[r];
}

/* The generic instances, and (with SQP_NX, SQP_NU) the fixed-size ones. */
/* The scratch arrays are declared here, where their sizes are constants in the fixed-size
 * instance: arrays of constant size can live in registers, variable-length ones cannot. */
#define INSTANCES(name, X, U, X1)                                                           \
    INSTANCE int factor_##name(                                                        \
        int x, int u, int x1, const double *h, const double *dg,                           \
        const double *a, const int *ix, const int *cn, const double *p1, double *m,         \
        double *p) {                                                                       \
        (void)x; (void)u; (void)x1;                                                        \
        double t[X1], tc[(X + U) * X1], tt[(X + U) * X1], acc[X + U], kt[U * X + 1],       \
            col[X];                                                                        \
        return factor_stage(X, U, X1, h, dg, a, ix, cn, p1, m, p, t, tc, tt, acc, kt,       \
                            col);                                                          \
    }                                                                                      \
    INSTANCE void back_##name(                                                         \
        int x, int u, int x1, const double *abt, const double *bj, const double *gj,        \
        const double *p1, const double *m, double *pv, double *mv) {                       \
        (void)x; (void)u; (void)x1;                                                        \
        double w[X1], mu[U + 1], pj[X], ml[X + U];                                         \
        back_stage(X, U, X1, abt, bj, gj, p1, m, pv, mv, w, mu, pj, ml);                    \
    }                                                                                      \
    INSTANCE void fwd_##name(                                                          \
        int x, int u, int x1, const double *a, const double *bj, const double *m,          \
        double *zj) {                                                                      \
        (void)x; (void)u; (void)x1;                                                        \
        double acc[U + 1], zn[X1];                                                         \
        fwd_stage(X, U, X1, a, bj, m, zj, acc, zn);                                         \
    }
INSTANCES(any, x, u, x1)
#if defined(SQP_NX) && defined(SQP_NU)
INSTANCES(fixed, SQP_NX, SQP_NU, SQP_NX)
#define IS_FIXED(x, u, x1) ((x) == SQP_NX && (u) == SQP_NU && (x1) == SQP_NX)
#else
#define IS_FIXED(x, u, x1) 0
#define factor_fixed factor_any
#define back_fixed back_any
#define fwd_fixed fwd_any
#endif

/* Factorise with the diagonal dg added to H (P_j, M_j as described above the kernels; P_0
 * is left as its Cholesky factor), and rho_c C'C to H_N. The recursion runs backward, so
 * stage j's factors depend on dg of stages j..N only: stages above `top` (the highest whose
 * dg changed since the last call) are kept, and the call redoes stages top..0. */
static int factorise(const problem *pr, const double *dg, double rho_c, int top) {
    const int n = pr->n, *nx = pr->nx, *nu = pr->nu;
    if (top < 0) return 0;
    /* Stage N: P_N = H_N + rho_c C'C + diag(dg_N). */
    if (top >= n) {
        int s = nx[n];
        const double *hj = pr->h + pr->oh[n];
        double *p = pr->P[n];
        if (rho_c != 0.0)
            for (int i = 0; i < s * s; ++i) p[i] = FMA(rho_c, pr->ctc[i], hj[i]);
        else
            memcpy(p, hj, sizeof(double) * (size_t)(s * s));
        const double *dn = dg + pr->oz[n];
        for (int i = 0; i < s; ++i) p[i + i * s] += dn[i];
    }
    for (int j = (top < n ? top : n - 1); j >= 0; --j) {
        int x = nx[j], u = nu[j], x1 = nx[j + 1];
        int info = (IS_FIXED(x, u, x1) ? factor_fixed : factor_any)(
            x, u, x1, pr->h + pr->oh[j], dg + pr->oz[j], pr->ab + pr->oab[j],
            pr->idx + pr->oab[j], pr->cnt + pr->oz[j], pr->P[j + 1], pr->M[j], pr->P[j]);
        if (info) return info;
    }
    /* x_0 is free: factorise P_0 in place. */
    if (chol(pr->P[0], nx[0], nx[0])) return 3;
    return 0;
}

/* Linear terms -> solution z, for fixed factorisation. g is the full gradient (q plus the
 * augmented-Lagrangian or barrier terms, the terminal part included), b the dynamics'
 * offsets (pr->b, or zeros for a response to g alone). */
static void vector_pass(const problem *pr, const double *g, const double *b, double *z) {
    const int n = pr->n, *nx = pr->nx, *nu = pr->nu;
    double *pv = pr->pv;
    /* pv holds p_{j+1}; m_j is stored in z's slots temporarily (z_j = m_j, then replaced). */
    memcpy(pv, g + pr->oz[n], sizeof(double) * nx[n]);
    for (int j = n - 1; j >= 0; --j) {
        int x = nx[j], u = nu[j], x1 = nx[j + 1];
        size_t o = pr->oz[j];
        (IS_FIXED(x, u, x1) ? back_fixed : back_any)(
            x, u, x1, pr->abt + pr->oab[j], b + pr->ob[j], g + o, pr->P[j + 1], pr->M[j],
            pv, z + o);
    }
    /* x_0 = -P_0^{-1} p_0 */
    for (int r = 0; r < nx[0]; ++r) z[r] = -pv[r];
    chol_solve(pr->P[0], nx[0], nx[0], z);
    for (int j = 0; j < n; ++j) {
        int x = nx[j], u = nu[j], x1 = nx[j + 1];
        (IS_FIXED(x, u, x1) ? fwd_fixed : fwd_any)(x, u, x1, pr->ab + pr->oab[j],
                                                   b + pr->ob[j], pr->M[j], z + pr->oz[j]);
    }
}

/* The highest stage whose active bounds differ from those of the current factors (n when
 * there are no factors, -1 when nothing changed). */
static int changed_top(const problem *p, const signed char *act) {
    if (!p->fact_valid || !p->reuse) return p->n;
    for (int j = p->n; j >= 0; --j) {
        size_t o = p->oz[j];
        int s = p->nx[j] + (j < p->n ? p->nu[j] : 0);
        if (memcmp(act + o, p->fact_act + o, (size_t)s)) return j;
    }
    return -1;
}

/* The equality-constrained QP with the bounds in `act` fixed at `target`: one factorisation,
 * then multiplier updates until the fixed bounds and C x_N = d hold to eq_tol (return 0), or
 * max_passes (return 2: the active set is inconsistent). */
static int solve_eqp(problem *p, const signed char *act, const double *target,
                     double *lam, double *lamc, double *z, qp_stats *st) {
    int top = changed_top(p, act);
    if (top >= 0)  /* the fixed bounds' weights, on the stages to redo */
        for (size_t i = 0, e = p->oz[top] + (size_t)p->nx[top] + (top < p->n ? p->nu[top] : 0);
             i < e; ++i)
            p->dg[i] = act[i] ? p->rho : 0.0;
    int info = factorise(p, p->dg, p->rho, top);
    p->fact_valid = !info;
    if (info) return info;
    memcpy(p->fact_act, act, (size_t)p->nw);
    st->stages += top < p->n ? top + 1 : p->n + 1;
    int on = (int)p->oz[p->n], xn = p->nx[p->n], nc = p->nc;
    for (int pass = 0; pass < p->max_passes; ++pass) {
        st->passes++;
        for (int i = 0; i < p->nw; ++i)
            p->g[i] = p->q[i] + (act[i] ? lam[i] - p->rho * target[i] : 0.0);
        for (int r = 0; r < xn; ++r) {
            double acc = 0.0;
            for (int k = 0; k < nc; ++k) acc += p->c[k + r * nc] * (lamc[k] - p->rho * p->d[k]);
            p->g[on + r] += acc;
        }
        vector_pass(p, p->g, p->b, z);
        double res = 0.0;
        for (int i = 0; i < p->nw; ++i)
            if (act[i]) {
                double e = z[i] - target[i];
                lam[i] += p->rho * e;
                p->dlam[i] = e;
                res = fmax(res, fabs(e));
            }
        for (int k = 0; k < nc; ++k) {
            double e = -p->d[k];
            for (int r = 0; r < xn; ++r) e += p->c[k + r * nc] * z[on + r];
            lamc[k] += p->rho * e;
            p->dlamc[k] = e;
            res = fmax(res, fabs(e));
        }
        if (res < p->eq_tol) return 0;
    }
    return 2;
}

/* A fixed bound whose multiplier has the wrong sign (lower: lam <= 0, upper: lam >= 0). */
static int wrong_sign(signed char a, double lam, double tol) {
    return (a < 0 && lam > tol) || (a > 0 && lam < -tol);
}

/* The part of the workspace both methods share (the stage pointers P, M and the offsets oz,
 * oh, oab, ob are the caller's arrays of n + 1 entries); returns the first free double. */
static double *setup(problem *pr, int n, const int *nx, const int *nu, const double *h,
                     const double *q, const double *ab, const double *b, int nc,
                     const double *c, const double *d, double **P, double **M, size_t *oz,
                     size_t *oh, size_t *oab, size_t *ob, double *work) {
    int nw = off_w(nx, nu, n) + nx[n];
    double *wp = work;
    for (int j = 0; j <= n; ++j) {
        int s = nx[j] + (j < n ? nu[j] : 0);
        P[j] = wp; wp += (size_t)nx[j] * nx[j];
        M[j] = wp; wp += (size_t)s * s;
    }
    /* Offsets of every stage's blocks (see problem). */
    oz[0] = oh[0] = oab[0] = ob[0] = 0;
    for (int j = 0; j < n; ++j) {
        int s = nx[j] + nu[j];
        oz[j + 1] = oz[j] + s;
        oh[j + 1] = oh[j] + (size_t)s * s;
        oab[j + 1] = oab[j] + (size_t)nx[j + 1] * s;
        ob[j + 1] = ob[j] + nx[j + 1];
    }
    *pr = (problem){.n = n, .nc = nc, .nw = nw, .nx = nx, .nu = nu, .h = h, .q = q, .ab = ab,
                    .b = b, .c = c, .d = d, .P = P, .M = M, .fact_valid = 0,
                    .oz = oz, .oh = oh, .oab = oab, .ob = ob};
    pr->g = wp; wp += nw;
    pr->pv = wp; wp += nw;
    pr->dg = wp; wp += nw;
    pr->dlam = wp; wp += nw;
    pr->dlamc = wp; wp += nc;
    pr->ctc = wp; wp += (size_t)nx[n] * nx[n];  /* C'C: filled by the active-set method */
    /* AB is fixed during a solve: its nonzero lists and its transpose serve every
     * factorisation and pass. */
    pr->abt = wp; wp += oab[n];
    int *idx = (int *)wp, *cnt = idx + oab[n];
    nonzeros(n, nx, nu, ab, idx, cnt, pr->abt);
    pr->idx = idx;
    pr->cnt = cnt;
    pr->fact_act = (signed char *)(idx + nz_ints(n, nx, nu));
    wp += (nz_ints(n, nx, nu) + 1) / 2 + (nw + sizeof(double) - 1) / sizeof(double);
    return wp;
}

int stage_qp_solve(int n, const int *nx, const int *nu, const double *h, const double *q,
                   const double *ab, const double *b, int nc, const double *c, const double *d,
                   const double *lb, const double *ub, signed char *act, double *lam,
                   double *lamc, double rho, double eq_tol, double kkt_tol, int max_outer,
                   int max_passes, int reuse, double *work, size_t work_size, double *z,
                   qp_stats *st) {
    if (work_size < stage_qp_workspace(n, nx, nu, nc)) return 4;
    double *P[n + 1], *M[n + 1];
    size_t oz[n + 1], oh[n + 1], oab[n + 1], ob[n + 1];
    problem pr;
    double *wp = setup(&pr, n, nx, nu, h, q, ab, b, nc, c, d, P, M, oz, oh, oab, ob, work);
    int nw = pr.nw;
    /* rho relative to the largest curvature: the multiplier updates contract by about
     * |H| / rho per pass, and a penalty Hessian can reach 1e6 here. */
    double hmax = 1.0;
    {
        const double *hj = h;
        for (int j = 0; j <= n; ++j) {
            int s = nx[j] + (j < n ? nu[j] : 0);
            for (int i = 0; i < s; ++i) hmax = fmax(hmax, fabs(hj[i + i * s]));
            hj += (size_t)s * s;
        }
    }
    /* C'C, the same at every full factorisation of this solve */
    int xn = nx[n];
    for (int cc = 0; cc < xn; ++cc)
        for (int r = 0; r < xn; ++r) {
            double acc = 0.0;
            for (int k = 0; k < nc; ++k) acc += c[k + r * nc] * c[k + cc * nc];
            pr.ctc[r + cc * xn] = acc;
        }
    pr.rho = rho * hmax;
    pr.eq_tol = eq_tol;
    pr.max_passes = max_passes;
    pr.reuse = reuse;
    double *target = wp; wp += nw;
    double *z0 = wp; wp += nw;
    double *lam0 = wp; wp += nw;
    double *lamc0 = wp; wp += nc;
    memset(st, 0, sizeof(*st));
    for (int i = 0; i < nw; ++i) {
        if (!act[i]) lam[i] = 0.0;
        target[i] = act[i] < 0 ? lb[i] : ub[i];
    }
    int info;
    for (int i = 0; i < nw; ++i) pr.dlam[i] = 0.0;

    /* 1. The guess, made dual feasible: release every fixed bound whose multiplier has the
     *    wrong sign, until none has (an inconsistent guess is dropped altogether). With the
     *    previous instant's set this is usually one solve, and the solution. */
    for (;;) {
        if (++st->outer > max_outer) return 1;
        info = solve_eqp(&pr, act, target, lam, lamc, z, st);
        if (info == 2) {  /* an inconsistent guess: start from no fixed bound */
            int held = 0;
            for (int i = 0; i < nw; ++i) { held += act[i] != 0; act[i] = 0; lam[i] = 0.0; }
            if (!held) return 2;  /* C x_N = d alone cannot be met */
            st->changes += held;
            for (int k = 0; k < nc; ++k) lamc[k] = 0.0;
            continue;
        }
        if (info) return info;
        int changes = 0;
        for (int i = 0; i < nw; ++i)
            if (act[i] && wrong_sign(act[i], lam[i], kkt_tol)) {
                act[i] = 0; lam[i] = 0.0; ++changes;
            }
        st->changes += changes;
        if (!changes) break;
    }
    /* 2. Dual active-set steps (Goldfarb-Idnani): take the most violated bound p and move
     *    its target from z_p to the bound. Solution and multipliers are affine in the
     *    target; if a fixed bound's multiplier reaches zero on the way, stop there, release
     *    it and go on. Every step keeps dual feasibility and raises the dual objective. */
    for (;;) {
        int p = -1;
        double worst = kkt_tol;
        for (int i = 0; i < nw; ++i) {
            if (act[i]) continue;
            double v = fmax(lb[i] - z[i], z[i] - ub[i]);
            if (v > worst) { worst = v; p = i; }
        }
        if (p < 0) break;
        memcpy(z0, z, sizeof(double) * nw);
        memcpy(lam0, lam, sizeof(double) * nw);
        memcpy(lamc0, lamc, sizeof(double) * nc);
        act[p] = z[p] < lb[p] ? -1 : 1;
        target[p] = act[p] < 0 ? lb[p] : ub[p];
        lam[p] = lam0[p] = 0.0;
        st->changes++;
        for (;;) {
            if (++st->outer > max_outer) return 1;
            info = solve_eqp(&pr, act, target, lam, lamc, z, st);
            if (info == 2) {
                /* p depends on the fixed bounds (and C x_N = d): the multipliers diverge
                 * along the dual direction dlam (the residual of the inconsistent system,
                 * orthogonal to the constraint normals). Pure dual step: move along it from
                 * lam0 until a fixed bound's multiplier reaches zero, release that bound; the
                 * primal point z0 stays. None reaching zero: the QP is infeasible. */
                double step = INFINITY;
                int drop = -1;
                for (int i = 0; i < nw; ++i) {
                    if (!act[i] || i == p) continue;
                    double dl = pr.dlam[i];
                    if ((act[i] < 0 && dl > 0.0) || (act[i] > 0 && dl < 0.0)) {
                        double t = -lam0[i] / dl;
                        if (t < step) { step = t; drop = i; }
                    }
                }
                if (drop < 0) return 2;
                for (int i = 0; i < nw; ++i)
                    lam0[i] = act[i] ? lam0[i] + step * pr.dlam[i] : 0.0;
                for (int k = 0; k < nc; ++k) lamc0[k] += step * pr.dlamc[k];
                act[drop] = 0; lam0[drop] = 0.0;
                st->changes++;
                memcpy(z, z0, sizeof(double) * nw);
                memcpy(lam, lam0, sizeof(double) * nw);
                memcpy(lamc, lamc0, sizeof(double) * nc);
                continue;
            }
            if (info) return info;
            double tau = 1.0;
            int drop = -1;
            for (int i = 0; i < nw; ++i)
                if (act[i] && i != p && wrong_sign(act[i], lam[i], kkt_tol)) {
                    double t = lam0[i] / (lam0[i] - lam[i]);
                    if (t < tau) { tau = t; drop = i; }
                }
            if (drop < 0) break;  /* p reached its bound */
            for (int i = 0; i < nw; ++i) {
                z[i] = z0[i] + tau * (z[i] - z0[i]);
                lam[i] = lam0[i] + tau * (lam[i] - lam0[i]);
            }
            for (int k = 0; k < nc; ++k) lamc[k] = lamc0[k] + tau * (lamc[k] - lamc0[k]);
            act[drop] = 0; lam[drop] = 0.0;
            st->changes++;
            memcpy(z0, z, sizeof(double) * nw);
            memcpy(lam0, lam, sizeof(double) * nw);
            memcpy(lamc0, lamc, sizeof(double) * nc);
        }
    }
    for (int i = 0; i < nw; ++i) st->n_active += act[i] != 0;
    return 0;
}

/* ---- Interior point: the same QP by Mehrotra's predictor-corrector method ----
 *
 * For QPs whose active set changes a lot from one call to the next (a region moving across
 * the horizon), where the dual active-set method above needs one factorisation per change.
 * Each bound has a slack and a multiplier, s_l = z - lb, s_u = ub - z, lam_l, lam_u > 0;
 * every iteration is one Riccati factorisation of H + Sigma, Sigma = lam_l/s_l + lam_u/s_u
 * on the bounded entries, and two solves (predictor, corrector) with that factorisation.
 *
 * The Newton step written for the new point z+ rather than the step: z+ solves
 *     min 1/2 z'(H + Sigma)z + g'z   s.t. x_{j+1} = AB_j z_j + b_j,  C x_N = d,
 *     g = q - Sigma_l (lb + s_l) - Sigma_u (ub - s_u) - t_l / s_l + t_u / s_u,
 * with t = 0 (predictor) or sigma mu - ds_aff dlam_aff (corrector); the dynamics' and the
 * terminal multipliers drop out of it, so they are never stored. The terminal rows are
 * exact: a terminal gradient C'nu moves x_N linearly in nu, and a backward sweep of the
 * cost-to-go's terms in nu over the same factors (schur) gives the nc x nc Schur complement
 * S = dC x_N / dnu and the feedforward gains of nu, so that one solve without the rows, nu
 * from S nu = d - C x_N, and a forward pass of the correction meet them. (The augmented
 * Lagrangian of the active-set method fails here: Sigma spans 1e-8..1e8 and more, and no
 * single weight suits both ends.)
 *
 * The start is the QP without its bounds but a curvature on them, the slacks and
 * multipliers pushed inside; one step length for primal and dual. The iterate kept is the
 * best (smallest max(mu, residual)): once lam / s spans more than double precision
 * resolves, the solves lose accuracy, in the weakly determined directions first.
 *
 * Return: 0 converged (mu, the slacks' residuals and the linear rows' residuals relative to
 * 1 + max|z| below tol); 1 the best iterate after max_iter iterations (or once the residuals
 * grow by 1e6); 3 a factorisation was not positive definite; 4 workspace too small. z is
 * the iterate, lam = lam_u - lam_l (< 0 at a lower bound), act the bounds whose lam / s
 * exceeds IPM_ACTIVE (-1 lower, +1 upper): the guess of the active set that the active-set
 * method then polishes (StageQP.interior_point). */
typedef struct {
    int iter;    /* interior-point iterations */
    double mu;   /* mean complementarity s * lam at return */
    double res;  /* largest residual of the slacks and the linear rows at return */
} ipm_stats;

size_t stage_ipm_workspace(int n, const int *nx, const int *nu, int nc) {
    size_t nw = 0, nb = 0;
    for (int j = 0; j <= n; ++j) {
        nw += nx[j] + (j < n ? nu[j] : 0);
        if (j < n) nb += nx[j + 1];
    }
    /* the shared part; sl, su, ll, lu, dsl, dsu, dll, dlu, tl, tu, zn, z, lo, up, 1/sl,
     * 1/su, the masks of the bounded sides and the terminal correction dz (nw each); zero
     * b; -S and nu; X_0 and the K~_j (nc x nx_0, at most nc x nw); Pi_j, Pi_{j+1} and E of
     * the Schur complement */
    int mxs = 0;
    for (int j = 0; j <= n; ++j) {
        int s = nx[j] + (j < n ? nu[j] : 0);
        mxs = s > mxs ? s : mxs;
    }
    return stage_qp_workspace(n, nx, nu, nc) + 19 * nw + nb + (size_t)nc * (nc + 1)
           + (size_t)nc * (nx[0] + nw) + 3 * (size_t)nc * mxs;
}

/* Largest residual of the dynamics and of C x_N = d at z (by columns of AB, as the forward
 * pass: sums along the rows, which vectorise). */
static double linear_residual(const problem *pr, const double *z, double *acc) {
    const int n = pr->n, *nx = pr->nx, *nu = pr->nu;
    double res = 0.0;
    for (int j = 0; j < n; ++j) {
        int s = nx[j] + nu[j], x1 = nx[j + 1];
        const double *a = pr->ab + pr->oab[j], *zj = z + pr->oz[j], *zn = z + pr->oz[j + 1];
        const double *bj = pr->b + pr->ob[j];
        for (int r = 0; r < x1; ++r) acc[r] = bj[r] - zn[r];
        for (int cc = 0; cc < s; ++cc) {
            double v = zj[cc];
            const double *col = a + (size_t)cc * x1;
            for (int r = 0; r < x1; ++r) acc[r] = FMA(col[r], v, acc[r]);
        }
        for (int r = 0; r < x1; ++r) res = fabs(acc[r]) > res ? fabs(acc[r]) : res;
    }
    const double *xn = z + pr->oz[n];
    for (int k = 0; k < pr->nc; ++k) {
        double e = -pr->d[k];
        for (int r = 0; r < nx[n]; ++r) e += pr->c[k + r * pr->nc] * xn[r];
        res = fabs(e) > res ? fabs(e) : res;
    }
    return res;
}

/* The terminal rows' part of the factorisation (see schur): the Cholesky factor of -S, the
 * feedforward gains K~_j = -M_uu^-1 E_u (nu_j x nc each, by rows, concatenated) and
 * X_0 = -P_0^-1 Pi_0 (nx_0 x nc, by rows): a terminal gradient C'nu moves u_j by
 * K~_j nu + K_j dx_j and x_0 by X_0 nu. */
typedef struct {
    double *sneg, *kt, *x0, *nu, *dz, *zero_b;
} terminal;

/* The solution z of the equality-constrained QP with the current factors and gradient g,
 * C x_N = d included: one Riccati solve without it, then nu = (-S)^-1 (C x_N - d) and the
 * correction, the forward pass of the responses (K~_j nu, X_0 nu) with zero offsets. */
static void solve_terminal(const problem *pr, const terminal *tm, const double *g, double *z) {
    const int n = pr->n, nc = pr->nc, xn = pr->nx[n], *nx = pr->nx, *nu = pr->nu;
    vector_pass(pr, g, pr->b, z);
    if (nc == 0) return;
    const double *x = z + pr->oz[n];
    for (int k = 0; k < nc; ++k) {
        double e = -pr->d[k];
        for (int r = 0; r < xn; ++r) e += pr->c[k + r * nc] * x[r];
        tm->nu[k] = e;
    }
    chol_solve(tm->sneg, nc, nc, tm->nu);
    double *dz = tm->dz;
    for (int r = 0; r < nx[0]; ++r) {
        double acc = 0.0;
        for (int k = 0; k < nc; ++k) acc += tm->x0[r * nc + k] * tm->nu[k];
        dz[r] = acc;
    }
    const double *kt = tm->kt;
    for (int j = 0; j < n; ++j) {
        int x_ = nx[j], u = nu[j], x1 = nx[j + 1];
        double *dj = dz + pr->oz[j];
        for (int i2 = 0; i2 < u; ++i2) {
            double acc = 0.0;
            for (int k = 0; k < nc; ++k) acc += kt[i2 * nc + k] * tm->nu[k];
            dj[x_ + i2] = acc;
        }
        kt += (size_t)u * nc;
        (IS_FIXED(x_, u, x1) ? fwd_fixed : fwd_any)(x_, u, x1, pr->ab + pr->oab[j],
                                                    tm->zero_b + pr->ob[j], pr->M[j], dj);
    }
    for (int r = 0; r < pr->nw; ++r) z[r] += dz[r];
}

/* For a block with Cholesky factor L (n x n, stride ld) of M and the rows y (n x nc, by
 * rows) of the terminal terms' E: y becomes L^-1 y, sneg gets + y'y = E' M^-1 E, and out
 * (n x nc, by rows) -M^-1 E, all nc columns at once. */
KERNEL void eliminate(const int nc, const double *restrict l, int n, int ld,
                      double *restrict y, double *restrict sneg, double *restrict out) {
    for (int i = 0; i < n; ++i) {  /* forward substitution */
        double *yi = y + (size_t)i * nc;
        for (int k2 = 0; k2 < i; ++k2) {
            double v = l[i + k2 * ld];
            const double *yk = y + (size_t)k2 * nc;
            UNROLL for (int k = 0; k < nc; ++k) yi[k] = FMA(-v, yk[k], yi[k]);
        }
        double dii = l[i + i * ld];
        UNROLL for (int k = 0; k < nc; ++k) yi[k] /= dii;
    }
    for (int r = 0; r < nc; ++r)
        for (int i = 0; i < n; ++i) {
            double v = y[(size_t)i * nc + r];
            const double *yi = y + (size_t)i * nc;
            double *sr = sneg + (size_t)r * nc;
            UNROLL for (int k = 0; k < nc; ++k) sr[k] = FMA(v, yi[k], sr[k]);
        }
    for (int i = n - 1; i >= 0; --i) {  /* backward substitution, negated */
        double *oi = out + (size_t)i * nc;
        UNROLL for (int k = 0; k < nc; ++k) oi[k] = y[(size_t)i * nc + k];
        for (int k2 = i + 1; k2 < n; ++k2) {
            double v = l[k2 + i * ld];
            const double *ok = out + (size_t)k2 * nc;
            UNROLL for (int k = 0; k < nc; ++k) oi[k] = FMA(v, ok[k], oi[k]);
        }
        double dii = l[i + i * ld];
        UNROLL for (int k = 0; k < nc; ++k) oi[k] /= -dii;
    }
}

/* The Schur complement of the terminal rows for the current factors: S = dC x_N / dnu, the
 * response of C x_N to a terminal gradient C'nu, by a backward recursion of the
 * cost-to-go's terms in nu (Bryson and Ho's sweep): with Pi_N = C', Omega_N = 0,
 *     E = AB_j' Pi_{j+1},   Pi_j = E_x + K_j' E_u,   Omega_j = Omega_{j+1} - E_u' M_uu^-1 E_u,
 * and, x_0 being free, S = Omega_0 - Pi_0' P_0^-1 Pi_0 (negative definite). Stores the
 * Cholesky factor of -S in sneg; pi, pi1 (nx_max x nc) and e (s_max x nc) are scratch.
 * Returns 3 when -S is not positive definite. */
KERNEL int schur_kernel(const int nc, const problem *pr, double *pi, double *pi1, double *e,
                        const terminal *tm) {
    double *restrict sneg = tm->sneg;
    double *ktj = tm->kt;  /* K~_j, filled from the last stage down */
    for (int j = 0; j < pr->n; ++j) ktj += (size_t)pr->nu[j] * nc;
    /* Pi and E are stored by rows (entry (r, k) at r * nc + k): every product then runs
     * along a row of nc numbers, which vectorises, over the nonzeros of AB only. */
    const int n = pr->n, *nx = pr->nx, *nu = pr->nu;
    for (int r = 0; r < nx[n]; ++r)
        for (int k = 0; k < nc; ++k) pi1[r * nc + k] = pr->c[k + r * nc];
    for (int i = 0; i < nc * nc; ++i) sneg[i] = 0.0;  /* -Omega */
    for (int j = n - 1; j >= 0; --j) {
        int x = nx[j], u = nu[j], x1 = nx[j + 1], s = x + u;
        const double *a = pr->ab + pr->oab[j], *m = pr->M[j];
        const int *ix = pr->idx + pr->oab[j], *cn = pr->cnt + pr->oz[j];
        /* E = AB' Pi_{j+1}, by rows (the sums of nc entries: registers when nc is a
         * constant) */
        double acc[nc];
        columns_times(nc, s, x1, a, ix, cn, pi1, acc, e);
        const double *kt = m + (size_t)x * s, *luu = m + x + (size_t)x * s;
        for (int r = 0; r < x; ++r) {  /* Pi_j = E_x + K' E_u */
            double acc[nc];
            UNROLL for (int k = 0; k < nc; ++k) acc[k] = e[(size_t)r * nc + k];
            for (int i = 0; i < u; ++i) {
                double v = kt[r + (size_t)i * s];
                const double *eu = e + (size_t)(x + i) * nc;
                UNROLL for (int k = 0; k < nc; ++k) acc[k] = FMA(v, eu[k], acc[k]);
            }
            double *pr_ = pi + (size_t)r * nc;
            UNROLL for (int k = 0; k < nc; ++k) pr_[k] = acc[k];
        }
        if (u > 0) {  /* -Omega += E_u' M_uu^-1 E_u; K~_j = -M_uu^-1 E_u */
            double y[u * nc];
            memcpy(y, e + (size_t)x * nc, sizeof(double) * (size_t)(u * nc));
            ktj -= (size_t)u * nc;
            eliminate(nc, luu, u, s, y, sneg, ktj);
        }
        double *t = pi1; pi1 = pi; pi = t;  /* Pi_j becomes the next stage's Pi_{j+1} */
    }
    /* x_0 free: -S = -Omega_0 + Pi_0' P_0^-1 Pi_0; X_0 = -P_0^-1 Pi_0 */
    eliminate(nc, pr->P[0], nx[0], nx[0], pi1, sneg, tm->x0);
    return chol(sneg, nc, nc) ? 3 : 0;
}
INSTANCE int schur_any(const problem *pr, double *pi, double *pi1, double *e,
                       const terminal *tm) {
    return schur_kernel(pr->nc, pr, pi, pi1, e, tm);
}
#ifdef SQP_NC  /* the number of terminal rows as a constant: the rows of nc fit registers */
INSTANCE int schur_fixed(const problem *pr, double *pi, double *pi1, double *e,
                         const terminal *tm) {
    return schur_kernel(SQP_NC, pr, pi, pi1, e, tm);
}
#define schur(pr, pi, pi1, e, tm) \
    ((pr)->nc == SQP_NC ? schur_fixed : schur_any)(pr, pi, pi1, e, tm)
#else
#define schur schur_any
#endif

/* Constants of the interior point (see stage_qp_ipm). The start scales with the cost (its
 * curvature with max|H|, its multipliers with max|q|): the cost scaled by c gives the same
 * start z and multipliers c times larger, as the moving design's are 20 times the paper
 * barrier's. Chosen on the QPs that went to the interior point on the swept pillar
 * (benchmarks/swept_pillar.py), 213 of the paper's barrier and 503 of the moving design: in
 * iterations, median / p99 / max, 12 / 14 / 17 and 23 / 44 / 50 from a fixed start
 * (multipliers 1000 / slack, curvature 100), 12 / 14 / 17 and 13 / 19 / 21 from this one.
 * (On the paper barrier's QPs HPIPM's cold start took 13-45, a start at z = 0 about 19.) */
#define IPM_CURVATURE 1e-3   /* the start: the QP without bounds, IPM_CURVATURE max|H| on them; */
#define IPM_SLACK 1.0        /* each slack at least this, */
#define IPM_MU0 0.01         /* each multiplier IPM_MU0 max|q| / slack */
#define IPM_TAU 0.995        /* the fraction of the step to the boundary taken */
#define IPM_ACTIVE 1e4       /* a bound whose lam / s exceeds this is guessed active */
#define MIN(a, b) ((a) < (b) ? (a) : (b))
#define MAX(a, b) ((a) > (b) ? (a) : (b))

int stage_qp_ipm(int n, const int *nx, const int *nu, const double *h, const double *q,
                 const double *ab, const double *b, int nc, const double *c, const double *d,
                 const double *lb, const double *ub, double tol, int max_iter, double *work,
                 size_t work_size, double *zbest, double *lbest, signed char *abest,
                 ipm_stats *st) {
    if (work_size < stage_ipm_workspace(n, nx, nu, nc)) return 4;
    double *P[n + 1], *M[n + 1];
    size_t oz[n + 1], oh[n + 1], oab[n + 1], ob[n + 1];
    problem pr;
    setup(&pr, n, nx, nu, h, q, ab, b, nc, c, d, P, M, oz, oh, oab, ob, work);
    const int nw = pr.nw;
    int mxs = 0;  /* the widest stage */
    for (int j = 0; j <= n; ++j) mxs = MAX(mxs, nx[j] + (j < n ? nu[j] : 0));
    double *wp = work + stage_qp_workspace(n, nx, nu, nc);
    /* per bounded entry: slacks, multipliers, their steps, the corrector's targets t; for
     * an unbounded side s = 1 and lam = 0 throughout, so it adds nothing anywhere */
    double *sl = wp; wp += nw;
    double *su = wp; wp += nw;
    double *ll = wp; wp += nw;
    double *lu = wp; wp += nw;
    double *dsl = wp; wp += nw;
    double *dsu = wp; wp += nw;
    double *dll = wp; wp += nw;
    double *dlu = wp; wp += nw;
    double *tl = wp; wp += nw;
    double *tu = wp; wp += nw;
    double *zn = wp; wp += nw;
    double *z = wp; wp += nw;
    double *lo = wp; wp += nw;  /* the bounds, 0 where infinite */
    double *isl = wp; wp += nw;  /* 1 / s */
    double *isu = wp; wp += nw;
    double *hasl = wp; wp += nw;  /* 1 where bounded, else 0 */
    double *hasu = wp; wp += nw;
    double *up = wp; wp += nw;
    double *zero_b = wp; wp += ob[n];
    terminal tm = {.zero_b = zero_b};
    tm.sneg = wp; wp += (size_t)nc * nc;
    tm.nu = wp; wp += nc;
    tm.x0 = wp; wp += (size_t)nc * nx[0];
    tm.kt = wp; wp += (size_t)nc * oz[n];
    tm.dz = wp; wp += nw;
    double *pi = wp; wp += (size_t)nc * mxs;
    double *pi1 = wp; wp += (size_t)nc * mxs;
    double *ek = wp; wp += (size_t)nc * mxs;
    memset(zero_b, 0, sizeof(double) * ob[n]);
    memset(tl, 0, sizeof(double) * nw);
    memset(tu, 0, sizeof(double) * nw);
    memset(st, 0, sizeof(*st));
    double *g = pr.g, *dg = pr.dg;
    signed char *hl = (signed char *)pr.fact_act;  /* which sides are bounded */
    /* The element-wise loops below (IVDEP) read and write arrays that never overlap, all
     * carved from the workspace, which the compiler cannot prove: told so, it vectorises
     * them. Each entry's arithmetic is the same, so the iterates are the same bit for bit
     * (the loops that sum or compare in order stay as they are). */
    int m = 0;
    for (int i = 0; i < nw; ++i) {
        int a = isfinite(lb[i]), bb = isfinite(ub[i]);
        hl[i] = (signed char)(a | (bb << 1));
        lo[i] = a ? lb[i] : 0.0;
        hasl[i] = a ? 1.0 : 0.0;
        hasu[i] = bb ? 1.0 : 0.0;
        up[i] = bb ? ub[i] : 0.0;
        m += a + bb;
    }
#define HAS_L(i) (hl[i] & 1)
#define HAS_U(i) (hl[i] & 2)
    /* Start: z minimises the QP without its bounds, with curvature IPM_CURVATURE max|H| on
     * the bounded entries (the dynamics and C x_N = d met); each slack at least IPM_SLACK,
     * each multiplier IPM_MU0 max|q| / slack. (max|·| at least 1.) */
    /* max|H| over every block (about 17,000 entries at N = 35): four running maxima, which
     * the compiler vectorises, where one is a chain of dependent comparisons; the same
     * number (a maximum is exact in any order) */
    double hm[4] = {0.0, 0.0, 0.0, 0.0};
    const size_t nh = oh[n] + (size_t)nx[n] * nx[n];
    size_t ih = 0;
    for (; ih + 4 <= nh; ih += 4)
        for (int k = 0; k < 4; ++k) hm[k] = MAX(hm[k], fabs(h[ih + k]));
    for (; ih < nh; ++ih) hm[0] = MAX(hm[0], fabs(h[ih]));
    double hmax = MAX(MAX(hm[0], hm[1]), MAX(hm[2], hm[3]));
    hmax = IPM_CURVATURE * MAX(hmax, 1.0);
    for (int i = 0; i < nw; ++i) dg[i] = hl[i] ? hmax : 0.0;
    int info = factorise(&pr, dg, 0.0, n);
    if (info) return info;
    if (nc > 0 && schur(&pr, pi, pi1, ek, &tm)) return 3;
    solve_terminal(&pr, &tm, q, z);
    double mu0 = 0.0;
    for (int i = 0; i < nw; ++i) mu0 = MAX(mu0, fabs(q[i]));
    mu0 = IPM_MU0 * MAX(mu0, 1.0);
    for (int i = 0; i < nw; ++i) {
        sl[i] = HAS_L(i) ? MAX(z[i] - lo[i], IPM_SLACK) : 1.0;
        su[i] = HAS_U(i) ? MAX(up[i] - z[i], IPM_SLACK) : 1.0;
        ll[i] = HAS_L(i) ? mu0 / sl[i] : 0.0;
        lu[i] = HAS_U(i) ? mu0 / su[i] : 0.0;
    }
    /* The best iterate (smallest max(mu, residual)) is returned: once lam / s spans more
     * than double precision resolves, the solves lose accuracy and the residuals grow. */
    double best = INFINITY;
    info = 1;
    for (int it = 0;; ++it) {
        /* complementarity, and the residuals: slacks; dynamics and C x_N = d relative to
         * the size of z (a Riccati solve meets them up to its rounding) */
        double mu = 0.0, rs = 0.0, zmax = 0.0;
        for (int i = 0; i < nw; ++i) {
            mu += sl[i] * ll[i] + su[i] * lu[i];
            if (HAS_L(i)) rs = MAX(rs, fabs(z[i] - lo[i] - sl[i]));
            if (HAS_U(i)) rs = MAX(rs, fabs(up[i] - z[i] - su[i]));
            zmax = MAX(zmax, fabs(z[i]));
        }
        mu = m ? mu / m : 0.0;
        rs = MAX(rs, linear_residual(&pr, z, g) / (1.0 + zmax));
        double merit = MAX(mu, rs);
        if (merit < best) {
            best = merit;
            st->mu = mu;
            st->res = rs;
            memcpy(zbest, z, sizeof(double) * nw);
            for (int i = 0; i < nw; ++i) {
                lbest[i] = lu[i] - ll[i];
                abest[i] = ll[i] > IPM_ACTIVE * sl[i] ? -1 : lu[i] > IPM_ACTIVE * su[i] ? 1 : 0;
            }
        }
        if (mu < tol && rs < tol) { info = 0; break; }
        if (it >= max_iter || merit > 1e6 * best) break;
        st->iter = it + 1;
        /* factorise H + Sigma, Sigma = lam_l / s_l + lam_u / s_u */
        IVDEP
        for (int i = 0; i < nw; ++i) {
            isl[i] = 1.0 / sl[i];
            isu[i] = 1.0 / su[i];
            dg[i] = ll[i] * isl[i] + lu[i] * isu[i];
        }
        pr.fact_valid = 0;
        info = factorise(&pr, dg, 0.0, n);
        if (info) return info;
        if (nc > 0 && schur(&pr, pi, pi1, ek, &tm)) return 3;
        info = 1;
        /* predictor (t = 0), then the corrector with Mehrotra's centring and second-order
         * terms; one step length for primal and dual (split ones leave a stationarity
         * residual that the solution carries in its weakly determined entries) */
        double alpha = 1.0;
        for (int pass = 0; pass < 2; ++pass) {
            IVDEP
            for (int i = 0; i < nw; ++i)
                g[i] = q[i] - ll[i] * isl[i] * (lo[i] + sl[i]) - lu[i] * isu[i] * (up[i] - su[i])
                       - tl[i] * isl[i] + tu[i] * isu[i];
            solve_terminal(&pr, &tm, g, zn);
            IVDEP
            for (int i = 0; i < nw; ++i) {  /* (an unbounded side: all 0, as its lam) */
                double dz = zn[i] - z[i];
                dsl[i] = hasl[i] * (dz + (z[i] - lo[i] - sl[i]));
                dll[i] = -ll[i] + (tl[i] - ll[i] * dsl[i]) * isl[i];
                dsu[i] = hasu[i] * (-dz + (up[i] - z[i] - su[i]));
                dlu[i] = -lu[i] + (tu[i] - lu[i] * dsu[i]) * isu[i];
            }
            /* the largest step <= 1 that keeps s, lam >= 0; a division only where a bound
             * binds tighter than the step so far */
            double amax = 1.0;
            for (int i = 0; i < nw; ++i) {
                if (HAS_L(i)) {
                    if (sl[i] < -amax * dsl[i]) amax = sl[i] / -dsl[i];
                    if (ll[i] < -amax * dll[i]) amax = ll[i] / -dll[i];
                }
                if (HAS_U(i)) {
                    if (su[i] < -amax * dsu[i]) amax = su[i] / -dsu[i];
                    if (lu[i] < -amax * dlu[i]) amax = lu[i] / -dlu[i];
                }
            }
            if (pass == 0) {  /* sigma = (mu_aff / mu)^3 */
                double mu_aff = 0.0;
                for (int i = 0; i < nw; ++i)
                    mu_aff += (sl[i] + amax * dsl[i]) * (ll[i] + amax * dll[i])
                              + (su[i] + amax * dsu[i]) * (lu[i] + amax * dlu[i]);
                mu_aff = m ? mu_aff / m : 0.0;
                double ratio = mu > 0.0 ? mu_aff / mu : 0.0;
                double sigma_mu = ratio * ratio * ratio * mu;
                for (int i = 0; i < nw; ++i) {
                    tl[i] = HAS_L(i) ? sigma_mu - dsl[i] * dll[i] : 0.0;
                    tu[i] = HAS_U(i) ? sigma_mu - dsu[i] * dlu[i] : 0.0;
                }
            } else {
                alpha = MIN(1.0, IPM_TAU * amax);
            }
        }
        IVDEP
        for (int i = 0; i < nw; ++i) {
            z[i] += alpha * (zn[i] - z[i]);
            sl[i] += alpha * dsl[i];
            su[i] += alpha * dsu[i];
            ll[i] += alpha * dll[i];
            lu[i] += alpha * dlu[i];
            tl[i] = tu[i] = 0.0;
        }
    }
    pr.fact_valid = 0;
    return info;
#undef HAS_L
#undef HAS_U
}
