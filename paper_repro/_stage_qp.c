/* Stage-structured QP: Riccati recursion inside a warm-started dual active-set method.
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
 * Return: 0 solved; 1 max_outer EQPs used; 2 infeasible (or an EQP that could not be made
 * consistent); 3 a factorisation was not positive definite; 4 workspace too small.
 */
#include <math.h>
#include <string.h>

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
static int chol(double *a, int n, int ld) {
    for (int k = 0; k < n; ++k) {
        double d = a[k + k * ld];
        for (int i = 0; i < k; ++i) d -= a[k + i * ld] * a[k + i * ld];
        if (!(d > 0.0)) return 1;
        d = sqrt(d);
        a[k + k * ld] = d;
        for (int r = k + 1; r < n; ++r) {
            double s = a[r + k * ld];
            for (int i = 0; i < k; ++i) s -= a[r + i * ld] * a[k + i * ld];
            a[r + k * ld] = s / d;
        }
    }
    return 0;
}

/* Solve L L' v = v in place (L lower, stride ld). */
static void chol_solve(const double *l, int n, int ld, double *v) {
    for (int k = 0; k < n; ++k) {
        double s = v[k];
        for (int i = 0; i < k; ++i) s -= l[k + i * ld] * v[i];
        v[k] = s / l[k + k * ld];
    }
    for (int k = n - 1; k >= 0; --k) {
        double s = v[k];
        for (int i = k + 1; i < n; ++i) s -= l[i + k * ld] * v[i];
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
    /* g, pv, target, z0, lam0, dlam; scratch; lamc0, dlamc; the nonzero lists of the AB
     * columns (ints: one row index per entry of AB_j, one count per column), in doubles;
     * the active set of the current factors (chars) */
    return w + 6 * nw + mx + 2 * (size_t)nc + (nz_ints(n, nx, nu) + 1) / 2
           + (nw + sizeof(double) - 1) / sizeof(double);
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
 * the same order as a dense loop: skipped terms are exact zeros, so results are unchanged. */
static void nonzeros(int n, const int *nx, const int *nu, const double *ab, int *idx,
                     int *cnt) {
    for (int j = 0; j < n; ++j) {
        int s = nx[j] + nu[j], x1 = nx[j + 1];
        for (int cc = 0; cc < s; ++cc, ab += x1, idx += x1) {
            int m = 0;
            for (int k = 0; k < x1; ++k)
                if (ab[k] != 0.0) idx[m++] = k;
            *cnt++ = m;
        }
    }
}

/* Factorise with the current active set. P_j, and M_j holding L_uu (Cholesky of the input
 * block) and K_j = -M_uu^{-1} M_ux in its (u, x) block; P_0 is left as its Cholesky factor.
 * The recursion runs backward, so stage j's factors depend on the active bounds of stages
 * j..N only: stages above `top` (the highest whose bounds changed since the last call) are
 * kept, and the call redoes stages top..0. */
static int factorise(int n, const int *nx, const int *nu, const double *h, const double *ab,
                     const int *idx, const int *cnt, int nc, const double *c,
                     const signed char *act, double rho, double **P, double **M, int top) {
    const double *hj;
    if (top < 0) return 0;
    /* Stage N: P_N = H_N + rho C'C + rho on active entries. */
    if (top >= n) {
        int s = nx[n];
        hj = h;
        for (int j = 0; j < n; ++j) hj += (size_t)(nx[j] + nu[j]) * (nx[j] + nu[j]);
        double *p = P[n];
        memcpy(p, hj, sizeof(double) * s * s);
        for (int cc = 0; cc < s; ++cc)
            for (int r = 0; r < s; ++r) {
                double acc = 0.0;
                for (int k = 0; k < nc; ++k) acc += c[k + r * nc] * c[k + cc * nc];
                p[r + cc * s] += rho * acc;
            }
        int o = off_w(nx, nu, n);
        for (int i = 0; i < s; ++i)
            if (act[o + i]) p[i + i * s] += rho;
    }
    /* Backward over stages. */
    size_t h_off = 0, ab_off = 0;
    size_t h_offs[n + 1], ab_offs[n + 1];
    for (int j = 0; j < n; ++j) {
        h_offs[j] = h_off;
        ab_offs[j] = ab_off;
        h_off += (size_t)(nx[j] + nu[j]) * (nx[j] + nu[j]);
        ab_off += (size_t)nx[j + 1] * (nx[j] + nu[j]);
    }
    for (int j = (top < n ? top : n - 1); j >= 0; --j) {
        int x = nx[j], u = nu[j], s = x + u, x1 = nx[j + 1];
        const double *a = ab + ab_offs[j];
        const int *ix = idx + ab_offs[j], *cn = cnt + off_w(nx, nu, j);
        const double *p1 = P[j + 1];
        double *m = M[j];
        memcpy(m, h + h_offs[j], sizeof(double) * s * s);
        int o = off_w(nx, nu, j);
        for (int i = 0; i < s; ++i)
            if (act[o + i]) m[i + i * s] += rho;
        /* m += AB' P AB, one column of P AB at a time, over the nonzeros of AB. */
        double t[x1];
        for (int cc = 0; cc < s; ++cc) {
            if (!cn[cc]) continue;  /* a zero column of AB adds nothing */
            const double *acol = a + (size_t)cc * x1;
            const int *ic = ix + (size_t)cc * x1;
            for (int r = 0; r < x1; ++r) t[r] = 0.0;
            for (int i = 0; i < cn[cc]; ++i) {
                int k = ic[i];
                double v = acol[k];
                const double *pk = p1 + (size_t)k * x1;
                for (int r = 0; r < x1; ++r) t[r] += pk[r] * v;
            }
            for (int r = cc; r < s; ++r) {  /* lower triangle, then mirror */
                const double *ar = a + (size_t)r * x1;
                const int *ir = ix + (size_t)r * x1;
                double acc = 0.0;
                for (int i = 0; i < cn[r]; ++i) acc += ar[ir[i]] * t[ir[i]];
                m[r + cc * s] += acc;
            }
        }
        for (int cc = 0; cc < s; ++cc)
            for (int r = 0; r < cc; ++r) m[r + cc * s] = m[cc + r * s];
        /* Input block: Cholesky; K = -M_uu^{-1} M_ux stored over M_ux. */
        if (u > 0) {
            if (chol(m + x + x * s, u, s)) return 3;
            for (int cc = 0; cc < x; ++cc) {
                double v[u];
                for (int i = 0; i < u; ++i) v[i] = m[x + i + cc * s];
                chol_solve(m + x + x * s, u, s, v);
                for (int i = 0; i < u; ++i) m[x + i + cc * s] = -v[i];
            }
        }
        /* P_j = M_xx + M_xu K = M_xx + K' M_ux, with M_ux = M_xu' kept in the upper block. */
        /* Column by column, adding the u terms in the same order as a dot product would,
         * but along r, which the compiler vectorises. */
        double *p = P[j];
        for (int cc = 0; cc < x; ++cc)
            for (int r = 0; r < x; ++r) {
                double acc = m[r + cc * s];
                for (int i = 0; i < u; ++i) acc += m[r + (x + i) * s] * m[x + i + cc * s];
                p[r + cc * x] = acc;
            }
        for (int cc = 0; cc < x; ++cc)
            for (int r = cc + 1; r < x; ++r) {
                double v = 0.5 * (p[r + cc * x] + p[cc + r * x]);
                p[r + cc * x] = p[cc + r * x] = v;
            }
    }
    /* x_0 is free: factorise P_0 in place. */
    if (chol(P[0], nx[0], nx[0])) return 3;
    return 0;
}

/* Linear terms -> solution z, for fixed factorisation. g is the full gradient (q plus the
 * augmented-Lagrangian terms), gc the terminal part C'(lamc - rho d). */
static void vector_pass(int n, const int *nx, const int *nu, const double *ab,
                        const int *idx, const int *cnt, const double *b, const double *g,
                        double **P, double **M, double *pv, double *scratch, double *z) {
    size_t ab_offs[n + 1], b_offs[n + 1];
    size_t ab_off = 0, b_off = 0;
    for (int j = 0; j < n; ++j) {
        ab_offs[j] = ab_off;
        b_offs[j] = b_off;
        ab_off += (size_t)nx[j + 1] * (nx[j] + nu[j]);
        b_off += nx[j + 1];
    }
    /* pv holds p_{j+1}; m_j is stored in z's slots temporarily (z_j = m_j, then replaced). */
    int on = off_w(nx, nu, n);
    memcpy(pv, g + on, sizeof(double) * nx[n]);
    double *mvecs = z;  /* reuse: m_j at offset of stage j */
    for (int j = n - 1; j >= 0; --j) {
        int x = nx[j], u = nu[j], s = x + u, x1 = nx[j + 1];
        const double *a = ab + ab_offs[j];
        const double *p1 = P[j + 1];
        const double *m = M[j];
        int o = off_w(nx, nu, j);
        double *mv = mvecs + o;
        /* w = P_{j+1} b_j + p_{j+1} */
        double *w = scratch;
        for (int r = 0; r < x1; ++r) w[r] = pv[r];
        for (int k = 0; k < x1; ++k) {
            double v = b[b_offs[j] + k];
            if (v == 0.0) continue;
            for (int r = 0; r < x1; ++r) w[r] += p1[r + (size_t)k * x1] * v;
        }
        /* m = g_j + AB' w, over the nonzeros of AB */
        const int *ix = idx + ab_offs[j], *cn = cnt + o;
        for (int r = 0; r < s; ++r) {
            double acc = g[o + r];
            const double *ar = a + (size_t)r * x1;
            const int *ir = ix + (size_t)r * x1;
            for (int i = 0; i < cn[r]; ++i) acc += ar[ir[i]] * w[ir[i]];
            mv[r] = acc;
        }
        /* k_j = -M_uu^{-1} m_u (kept in mv's u slots); p_j = m_x + K' m_u */
        double mu[u > 0 ? u : 1];
        for (int i = 0; i < u; ++i) mu[i] = mv[x + i];
        for (int r = 0; r < x; ++r) {
            double acc = mv[r];
            for (int i = 0; i < u; ++i) acc += m[x + i + r * s] * mu[i];
            pv[r] = acc;
        }
        if (u > 0) {
            chol_solve(m + x + x * s, u, s, mu);
            for (int i = 0; i < u; ++i) mv[x + i] = -mu[i];
        }
    }
    /* x_0 = -P_0^{-1} p_0 */
    for (int r = 0; r < nx[0]; ++r) z[r] = -pv[r];
    chol_solve(P[0], nx[0], nx[0], z);
    /* Forward: u_j = K_j x_j + k_j, x_{j+1} = AB_j z_j + b_j. */
    for (int j = 0; j < n; ++j) {
        int x = nx[j], u = nu[j], s = x + u, x1 = nx[j + 1];
        const double *m = M[j];
        int o = off_w(nx, nu, j);
        double *zj = z + o;
        for (int i = 0; i < u; ++i) {
            double acc = zj[x + i];  /* k_j */
            for (int r = 0; r < x; ++r) acc += m[x + i + r * s] * zj[r];
            zj[x + i] = acc;
        }
        double *zn = z + o + s;
        const double *a = ab + ab_offs[j];
        for (int r = 0; r < x1; ++r) zn[r] = b[b_offs[j] + r];
        for (int cc = 0; cc < s; ++cc) {
            double v = zj[cc];
            if (v == 0.0) continue;
            const double *acol = a + (size_t)cc * x1;
            for (int r = 0; r < x1; ++r) zn[r] += acol[r] * v;
        }
    }
}

typedef struct {
    int n, nc, nw, max_passes;
    const int *nx, *nu, *idx, *cnt;  /* idx, cnt: nonzero lists of the AB columns */
    const double *h, *q, *ab, *b, *c, *d;
    double rho, eq_tol;
    double **P, **M, *g, *pv, *scratch;
    double *dlam, *dlamc;  /* last multiplier update: the dual direction when inconsistent */
    signed char *fact_act; /* the active set of the current factors, */
    int fact_valid;        /* if any (not at the start of a call, nor after a failed one) */
    int reuse;             /* 0: refactorise every stage every time (a check of the reuse) */
} problem;

/* The highest stage whose active bounds differ from those of the current factors (n when
 * there are no factors, -1 when nothing changed). */
static int changed_top(const problem *p, const signed char *act) {
    if (!p->fact_valid || !p->reuse) return p->n;
    for (int j = p->n; j >= 0; --j) {
        int o = off_w(p->nx, p->nu, j), s = p->nx[j] + (j < p->n ? p->nu[j] : 0);
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
    int info = factorise(p->n, p->nx, p->nu, p->h, p->ab, p->idx, p->cnt, p->nc, p->c, act,
                         p->rho, p->P, p->M, top);
    p->fact_valid = !info;
    if (info) return info;
    memcpy(p->fact_act, act, (size_t)p->nw);
    st->stages += top < p->n ? top + 1 : p->n + 1;
    int on = off_w(p->nx, p->nu, p->n), xn = p->nx[p->n], nc = p->nc;
    for (int pass = 0; pass < p->max_passes; ++pass) {
        st->passes++;
        for (int i = 0; i < p->nw; ++i)
            p->g[i] = p->q[i] + (act[i] ? lam[i] - p->rho * target[i] : 0.0);
        for (int r = 0; r < xn; ++r) {
            double acc = 0.0;
            for (int k = 0; k < nc; ++k) acc += p->c[k + r * nc] * (lamc[k] - p->rho * p->d[k]);
            p->g[on + r] += acc;
        }
        vector_pass(p->n, p->nx, p->nu, p->ab, p->idx, p->cnt, p->b, p->g, p->P, p->M, p->pv,
                    p->scratch, z);
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

int stage_qp_solve(int n, const int *nx, const int *nu, const double *h, const double *q,
                   const double *ab, const double *b, int nc, const double *c, const double *d,
                   const double *lb, const double *ub, signed char *act, double *lam,
                   double *lamc, double rho, double eq_tol, double kkt_tol, int max_outer,
                   int max_passes, int reuse, double *work, size_t work_size, double *z,
                   qp_stats *st) {
    if (work_size < stage_qp_workspace(n, nx, nu, nc)) return 4;
    int nw = off_w(nx, nu, n) + nx[n];
    double *P[n + 1], *M[n + 1];
    double *wp = work;
    for (int j = 0; j <= n; ++j) {
        int s = nx[j] + (j < n ? nu[j] : 0);
        P[j] = wp; wp += (size_t)nx[j] * nx[j];
        M[j] = wp; wp += (size_t)s * s;
    }
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
    problem pr = {n, nc, nw, max_passes, nx, nu, NULL, NULL, h, q, ab, b, c, d, rho * hmax,
                  eq_tol, P, M, NULL, NULL, NULL, NULL, NULL, NULL, 0, reuse};
    pr.g = wp; wp += nw;
    pr.pv = wp; wp += nw;
    double *target = wp; wp += nw;
    double *z0 = wp; wp += nw;
    double *lam0 = wp; wp += nw;
    pr.dlam = wp; wp += nw;
    double *lamc0 = wp; wp += nc;
    pr.dlamc = wp; wp += nc;
    pr.scratch = wp;
    {
        int mx = 0;
        for (int j = 0; j <= n; ++j) mx = nx[j] > mx ? nx[j] : mx;
        wp += mx;
    }
    /* AB is fixed during a solve: its nonzero lists serve every factorisation and pass. */
    int *idx = (int *)wp, *cnt = idx;
    for (int j = 0; j < n; ++j) cnt += (size_t)nx[j + 1] * (nx[j] + nu[j]);
    nonzeros(n, nx, nu, ab, idx, cnt);
    pr.idx = idx;
    pr.cnt = cnt;
    pr.fact_act = (signed char *)(idx + nz_ints(n, nx, nu));
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
