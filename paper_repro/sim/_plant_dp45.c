/* Plant integration over one zero-order-hold interval: Dormand-Prince 5(4) with the step
 * control of scipy's solve_ivp(method="RK45"), so that the compiled plant and solve_ivp take
 * the same steps and agree to rounding.
 *
 * This file is appended to CasADi's C code of the right-hand side f_c(x[12], u[4]) (see
 * paper_repro/plant.py), which defines f_c, casadi_real and casadi_int, and the work sizes
 * PLANT_SZ_ARG, PLANT_SZ_RES, PLANT_SZ_IW and PLANT_SZ_W.
 *
 * Replicated from scipy (integrate/_ivp/rk.py and common.py, unchanged since scipy 1.0):
 *  - initial step: Hairer, Norsett & Wanner II.4 (select_initial_step), capped by the interval;
 *  - error norm: RMS of err_i / (atol + max(|y_i|, |y_new_i|) rtol);
 *  - step factor: 0.9 err^(-1/5), within [0.2, 10], not above 1 right after a rejection;
 *  - minimum step 10 ulp(t); the last step is cut to end exactly at t = ts, whose state is
 *    the fifth-order solution itself (solve_ivp without t_eval returns it, no interpolation).
 */
#include <math.h>
#include <string.h>

#define PLANT_N 12

static const double DP_C_A[6][5] = {
    {0, 0, 0, 0, 0},
    {1.0 / 5, 0, 0, 0, 0},
    {3.0 / 40, 9.0 / 40, 0, 0, 0},
    {44.0 / 45, -56.0 / 15, 32.0 / 9, 0, 0},
    {19372.0 / 6561, -25360.0 / 2187, 64448.0 / 6561, -212.0 / 729, 0},
    {9017.0 / 3168, -355.0 / 33, 46732.0 / 5247, 49.0 / 176, -5103.0 / 18656}};
static const double DP_B[6] = {35.0 / 384, 0, 500.0 / 1113, 125.0 / 192, -2187.0 / 6784,
                               11.0 / 84};
static const double DP_E[7] = {-71.0 / 57600, 0, 71.0 / 16695, -71.0 / 1920,
                               17253.0 / 339200, -22.0 / 525, 1.0 / 40};

static int plant_rhs(const double *x, const double *u, double *f) {
    const casadi_real *arg[PLANT_SZ_ARG > 2 ? PLANT_SZ_ARG : 2] = {x, u};
    casadi_real *res[PLANT_SZ_RES > 1 ? PLANT_SZ_RES : 1] = {f};
    casadi_int iw[PLANT_SZ_IW > 1 ? PLANT_SZ_IW : 1];
    casadi_real w[PLANT_SZ_W > 1 ? PLANT_SZ_W : 1];
    return f_c(arg, res, iw, w, 0);
}

/* RMS norm, as scipy's common.norm: ||v|| / sqrt(n). */
static double rms(const double *v) {
    double s = 0.0;
    for (int i = 0; i < PLANT_N; ++i) s += v[i] * v[i];
    return sqrt(s) / sqrt((double)PLANT_N);
}

/* x(ts) from x(0) = x0 under constant input u. Returns 0 on success, 1 when the step size
 * fell below 10 ulp (scipy's TOO_SMALL_STEP), 2 when the right-hand side failed. stats[0]
 * counts accepted steps, stats[1] rejected ones, stats[2] right-hand-side evaluations. */
int plant_dp45(const double *x0, const double *u, double ts, double rtol, double atol,
               double *x_out, int *stats) {
    double y[PLANT_N], f[PLANT_N], K[7][PLANT_N], ytmp[PLANT_N], ynew[PLANT_N];
    double v[PLANT_N], scale[PLANT_N];
    stats[0] = stats[1] = stats[2] = 0;
    memcpy(y, x0, sizeof y);
    if (plant_rhs(y, u, f)) return 2;
    stats[2]++;

    /* Initial step (select_initial_step with max_step = inf, direction +1). */
    double h_abs;
    {
        for (int i = 0; i < PLANT_N; ++i) scale[i] = atol + fabs(y[i]) * rtol;
        for (int i = 0; i < PLANT_N; ++i) v[i] = y[i] / scale[i];
        double d0 = rms(v);
        for (int i = 0; i < PLANT_N; ++i) v[i] = f[i] / scale[i];
        double d1 = rms(v);
        double h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
        if (h0 > ts) h0 = ts;
        for (int i = 0; i < PLANT_N; ++i) ytmp[i] = y[i] + h0 * f[i];
        double f1[PLANT_N];
        if (plant_rhs(ytmp, u, f1)) return 2;
        stats[2]++;
        for (int i = 0; i < PLANT_N; ++i) v[i] = (f1[i] - f[i]) / scale[i];
        double d2 = rms(v) / h0;
        double h1 = (d1 <= 1e-15 && d2 <= 1e-15) ? fmax(1e-6, h0 * 1e-3)
                                                  : pow(0.01 / fmax(d1, d2), 1.0 / 5);
        h_abs = fmin(fmin(100 * h0, h1), ts);
    }

    double t = 0.0;
    const double exponent = -1.0 / 5;
    while (t < ts) {
        double min_step = 10 * fabs(nextafter(t, INFINITY) - t);
        if (h_abs < min_step) h_abs = min_step;
        int rejected = 0;
        double t_new, h;
        for (;;) {
            if (h_abs < min_step) return 1;
            h = h_abs;
            t_new = t + h;
            if (t_new - ts > 0) t_new = ts;
            h = t_new - t;
            h_abs = fabs(h);

            /* Stages K_0..K_5, the fifth-order solution and K_6 = f(y_new) (FSAL). */
            memcpy(K[0], f, sizeof f);
            for (int s = 1; s < 6; ++s) {
                for (int i = 0; i < PLANT_N; ++i) {
                    double dy = 0.0;
                    for (int k = 0; k < s; ++k) dy += K[k][i] * DP_C_A[s][k];
                    ytmp[i] = y[i] + dy * h;
                }
                if (plant_rhs(ytmp, u, K[s])) return 2;
                stats[2]++;
            }
            for (int i = 0; i < PLANT_N; ++i) {
                double acc = 0.0;
                for (int k = 0; k < 6; ++k) acc += K[k][i] * DP_B[k];
                ynew[i] = y[i] + h * acc;
            }
            if (plant_rhs(ynew, u, K[6])) return 2;
            stats[2]++;

            for (int i = 0; i < PLANT_N; ++i) {
                double err = 0.0;
                for (int k = 0; k < 7; ++k) err += K[k][i] * DP_E[k];
                double sc = atol + fmax(fabs(y[i]), fabs(ynew[i])) * rtol;
                v[i] = err * h / sc;
            }
            double error_norm = rms(v);
            if (error_norm < 1) {
                double factor = error_norm == 0 ? 10.0
                                                : fmin(10.0, 0.9 * pow(error_norm, exponent));
                if (rejected && factor > 1) factor = 1;
                h_abs *= factor;
                break;
            }
            h_abs *= fmax(0.2, 0.9 * pow(error_norm, exponent));
            rejected = 1;
            stats[1]++;
        }
        stats[0]++;
        t = t_new;
        memcpy(y, ynew, sizeof y);
        memcpy(f, K[6], sizeof f);
    }
    memcpy(x_out, y, sizeof y);
    return 0;
}
