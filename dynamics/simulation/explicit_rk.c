/*
 * nhgait: embedded explicit Runge-Kutta integration of one closed-loop right-hand side.
 *
 * This file is a template. nhgait.dynamics.compiled prepends the CasADi-generated functions
 *   nhg_rhs(t, t_c, y, p) -> ydot        (closed loop; t_c = min(t, t_hi) is the controller time)
 *   nhg_event(y, ydot, p) -> (g, gdot)   (singular-set measure and its rate; if NHG_HAS_EVENT)
 *   nhg_out(t, t_c, y, p) -> outputs     (evaluated at the output points)
 *   nhg_diag(t, t_c, y, p) -> diagnostic outputs (the blocks only the diagnostics read)
 * and the macros NHG_NY, NHG_NP, NHG_NOUT, NHG_NDIAG, NHG_HAS_EVENT, NHG_SZ_ARG, NHG_SZ_RES, NHG_SZ_IW,
 * NHG_SZ_W, and the tableau arrays of nhgait.dynamics.rk_tableaus (DOP853_*, DOPRI5_*); with
 * NHG_HAS_PROJECT also nhg_project(y, p) -> y (velocities projected onto the constraints), applied
 * to every accepted step and every output point (the next step restarts from the projected
 * state with a fresh f(t, y)).
 *
 * Method (Hairer, Norsett & Wanner I, II.4-II.6 and II.10): explicit stages, error estimate
 * of the embedded pair in the RMS norm with weights atol + rtol max(|y|, |y1|), step-size
 * controller h_new = h * clamp(safety * err^(-expo) * err_old^beta), continuous extension
 * y(t + theta h) = y + sum_d theta^(d+1) R_d, R_d = h sum_i dense[i][d] k_i.
 * Non-finite stages are treated as a rejected step (h shrinks); a non-finite right-hand side
 * at an accepted point, a step size below 16 eps |t| or max_steps accepted steps end the run
 * with a status. Stiffness detection: h |lambda| estimated from the two stages with c = 1; above
 * about half the stability limit (DOP853 3.0, DOPRI5 1.2) for 15 consecutive steps the step is
 * set by stability (see nhgait.dynamics.integrators.STIFF_LIMIT).
 * Events: the measure g(y) falling below ctl[NHG_C_EVTOL] is located by bisection on the
 * continuous extension.
 */
#include <float.h>
#include <math.h>
#include <string.h>

/* ---------------------------------------------------------------- return codes */
#define NHG_DONE 0              /* reached t_end */
#define NHG_PAUSED 1            /* step buffer full: call again to resume */
#define NHG_STEP_TOO_SMALL -1
#define NHG_MAX_STEPS -2
#define NHG_NONFINITE -3        /* non-finite right-hand side at an accepted point */
#define NHG_NONFINITE_TRIAL -4  /* every trial step beyond t produced non-finite stages */
#define NHG_EVENT -5            /* the event measure fell below its tolerance */
#define NHG_STIFF -6            /* stiffness detected and ctl[NHG_C_STOP_STIFF] set */

/* ---------------------------------------------------------------- ctl[] (doubles) */
#define NHG_C_T 0          /* in/out: current time */
#define NHG_C_H 1          /* in/out: next step size (0 = choose) */
#define NHG_C_RTOL 2
#define NHG_C_ATOL 3
#define NHG_C_HMAX 4
#define NHG_C_EVTOL 5      /* event threshold (<= 0: no event) */
#define NHG_C_ERROLD 6     /* in/out: previous error (PI controller) */
#define NHG_C_TSTIFF 7     /* out: time stiffness was first detected (NaN: never) */
#define NHG_C_TFAIL 8      /* out: time of the failure or event */
#define NHG_C_GLAST 9      /* out: event measure at the last accepted point */
#define NHG_C_STOP_STIFF 10
#define NHG_C_HLAMBDA 11   /* out: largest h|lambda| estimate seen */
#define NHG_NCTL 12

/* ---------------------------------------------------------------- cnt[] (long long) */
#define NHG_N_FEV 0
#define NHG_N_ACC 1
#define NHG_N_REJ 2
#define NHG_N_MAXSTEPS 3
#define NHG_N_IEVAL 4      /* in/out: next index into t_eval */
#define NHG_N_OUT 5        /* out: steps written into t_steps / y_steps */
#define NHG_N_STIFF 6      /* in/out: consecutive stiff estimates */
#define NHG_N_NONSTIFF 7
#define NHG_N_BAD 8        /* out: index of the first non-finite component */
#define NHG_NCNT 9

#define NHG_MAX_STAGES 16
#define NHG_MAX_DEGREE 8

typedef struct {
  int s_step, i_new, s_ext, degree, i_stiff;
  const double *c, *a, *b, *e, *e3, *dense;
  double expo, beta, safety, fac_min, fac_max, stab;
} nhg_method;

typedef struct {
  const double *p;
  double t_hi;
  long long *nfev;
  const casadi_real *arg[NHG_SZ_ARG + 4];
  casadi_real *res[NHG_SZ_RES + 1];
  casadi_int iw[NHG_SZ_IW + 1];
  casadi_real w[NHG_SZ_W + 1];
} nhg_ctx;

static const nhg_method NHG_METHODS[2] = {
  {12, 12, 16, DOP853_DEGREE, 11, DOP853_C, DOP853_A, DOP853_B, DOP853_E, DOP853_E3,
   DOP853_DENSE, 1.0 / 8.0, 0.0, 0.9, 1.0 / 3.0, 6.0, 3.0},
  {7, 6, 7, DOPRI5_DEGREE, 5, DOPRI5_C, DOPRI5_A, DOPRI5_B, DOPRI5_E, 0,
   DOPRI5_DENSE, 0.2 - 0.04 * 0.75, 0.04, 0.9, 0.2, 10.0, 1.2},
};

static int nhg_first_bad(const double *v, int n) {
  int i;
  for (i = 0; i < n; ++i)
    if (!isfinite(v[i])) return i;
  return -1;
}

static void nhg_f(nhg_ctx *cx, double t, const double *y, double *dy) {
  double tc = t < cx->t_hi ? t : cx->t_hi;
  cx->arg[0] = &t;
  cx->arg[1] = &tc;
  cx->arg[2] = y;
  cx->arg[3] = cx->p;
  cx->res[0] = dy;
  nhg_rhs(cx->arg, cx->res, cx->iw, cx->w, 0);
  ++*cx->nfev;
}

/* the event measure g(y) and, with ydot, its rate dg/dt = grad g . ydot */
static double nhg_g(nhg_ctx *cx, const double *y, const double *ydot, double *gdot) {
#if NHG_HAS_EVENT
  static const double zeros[NHG_NY] = {0};
  double g = 0.0, rate = 0.0;
  cx->arg[0] = y;
  cx->arg[1] = ydot ? ydot : zeros;
  cx->arg[2] = cx->p;
  cx->res[0] = &g;
  cx->res[1] = &rate;
  nhg_event(cx->arg, cx->res, cx->iw, cx->w, 0);
  if (gdot) *gdot = rate;
  return g;
#else
  (void)cx; (void)y; (void)ydot;
  if (gdot) *gdot = 0.0;
  return 1.0;
#endif
}

/* y <- project(y) (constraint stabilisation by projection), or nothing */
static void nhg_proj(nhg_ctx *cx, double *y) {
#if NHG_HAS_PROJECT
  double tmp[NHG_NY];
  memcpy(tmp, y, sizeof tmp);
  cx->arg[0] = tmp;
  cx->arg[1] = cx->p;
  cx->res[0] = y;
  nhg_project(cx->arg, cx->res, cx->iw, cx->w, 0);
#else
  (void)cx; (void)y;
#endif
}

/* ytmp = y + h sum_{j < i} a[i][j] k[j] */
static void nhg_stage_arg(const nhg_method *m, int i, double h, const double *y,
                          double k[][NHG_NY], double *ytmp) {
  int j, n;
  for (n = 0; n < NHG_NY; ++n) ytmp[n] = 0.0;
  for (j = 0; j < i; ++j) {
    double aij = m->a[i * m->s_ext + j];
    if (aij == 0.0) continue;
    for (n = 0; n < NHG_NY; ++n) ytmp[n] += aij * k[j][n];
  }
  for (n = 0; n < NHG_NY; ++n) ytmp[n] = y[n] + h * ytmp[n];
}

/* weighted RMS error of the embedded pair (DOP853: the combined 5th/3rd-order estimate) */
static double nhg_error(const nhg_method *m, double h, const double *y, const double *y1,
                        double k[][NHG_NY], double rtol, double atol) {
  double s5 = 0.0, s3 = 0.0;
  int i, n;
  for (n = 0; n < NHG_NY; ++n) {
    double sc = atol + rtol * fmax(fabs(y[n]), fabs(y1[n]));
    double e5 = 0.0, e3 = 0.0;
    for (i = 0; i < m->s_step; ++i) {
      e5 += m->e[i] * k[i][n];
      if (m->e3) e3 += m->e3[i] * k[i][n];
    }
    s5 += (e5 / sc) * (e5 / sc);
    s3 += (e3 / sc) * (e3 / sc);
  }
  if (!m->e3) return fabs(h) * sqrt(s5 / NHG_NY);
  {
    double deno = s5 + 0.01 * s3;
    if (deno <= 0.0) deno = 1.0;
    return fabs(h) * s5 / sqrt(NHG_NY * deno);
  }
}

/* Hairer-Wanner starting step: h0 from |y|/|f|, refined by one explicit Euler step */
static double nhg_initial_step(nhg_ctx *cx, const nhg_method *m, double t, const double *y,
                               const double *f0, double rtol, double atol, double hmax,
                               double span) {
  double d0 = 0.0, d1 = 0.0, d2 = 0.0, h0, h1, y1[NHG_NY], f1[NHG_NY];
  int n, order = m->e3 ? 8 : 5;
  for (n = 0; n < NHG_NY; ++n) {
    double sc = atol + rtol * fabs(y[n]);
    d0 += (y[n] / sc) * (y[n] / sc);
    d1 += (f0[n] / sc) * (f0[n] / sc);
  }
  d0 = sqrt(d0 / NHG_NY);
  d1 = sqrt(d1 / NHG_NY);
  h0 = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
  h0 = fmin(h0, fmin(hmax, span));
  for (n = 0; n < NHG_NY; ++n) y1[n] = y[n] + h0 * f0[n];
  nhg_f(cx, t + h0, y1, f1);
  for (n = 0; n < NHG_NY; ++n) {
    double sc = atol + rtol * fabs(y[n]);
    d2 += ((f1[n] - f0[n]) / sc) * ((f1[n] - f0[n]) / sc);
  }
  d2 = sqrt(d2 / NHG_NY) / h0;
  if (!isfinite(d2)) return h0 * 1e-3;
  if (fmax(d1, d2) <= 1e-15) h1 = fmax(1e-6, h0 * 1e-3);
  else h1 = pow(0.01 / fmax(d1, d2), 1.0 / (order + 1));
  return fmin(fmin(100.0 * h0, h1), fmin(hmax, span));
}

/* R_d = h sum_i dense[i][d] k_i, computing the extension-only stages first */
static void nhg_prepare_dense(nhg_ctx *cx, const nhg_method *m, double t, double h,
                              const double *y, double k[][NHG_NY], double R[][NHG_NY]) {
  int i, d, n;
  double ytmp[NHG_NY];
  for (i = m->i_new + 1; i < m->s_ext; ++i) {
    nhg_stage_arg(m, i, h, y, k, ytmp);
    nhg_f(cx, t + m->c[i] * h, ytmp, k[i]);
  }
  for (d = 0; d < m->degree; ++d) {
    for (n = 0; n < NHG_NY; ++n) R[d][n] = 0.0;
    for (i = 0; i < m->s_ext; ++i) {
      double c = m->dense[i * m->degree + d];
      if (c == 0.0) continue;
      for (n = 0; n < NHG_NY; ++n) R[d][n] += c * k[i][n];
    }
    for (n = 0; n < NHG_NY; ++n) R[d][n] *= h;
  }
}

static void nhg_dense(const nhg_method *m, double theta, const double *y, double R[][NHG_NY],
                      double *out) {
  int d, n;
  for (n = 0; n < NHG_NY; ++n) {
    double acc = R[m->degree - 1][n];
    for (d = m->degree - 2; d >= 0; --d) acc = acc * theta + R[d][n];
    out[n] = y[n] + theta * acc;
  }
}

/* the stiffness test of HNW II (sec. IV.2): h|lambda| ~ h |f(y1) - f(Y)| / |y1 - Y| */
static void nhg_stiffness(const nhg_method *m, double h, const double *y1, const double *ystiff,
                          double k[][NHG_NY], double *ctl, long long *cnt, double t_new) {
  double num = 0.0, den = 0.0, hl;
  int n;
  for (n = 0; n < NHG_NY; ++n) {
    double a = k[m->i_new][n] - k[m->i_stiff][n], b = y1[n] - ystiff[n];
    num += a * a;
    den += b * b;
  }
  if (den <= 0.0) return;
  hl = fabs(h) * sqrt(num / den);
  if (hl > ctl[NHG_C_HLAMBDA]) ctl[NHG_C_HLAMBDA] = hl;
  if (hl > m->stab) {
    cnt[NHG_N_NONSTIFF] = 0;
    if (++cnt[NHG_N_STIFF] >= 15 && isnan(ctl[NHG_C_TSTIFF])) ctl[NHG_C_TSTIFF] = t_new;
  } else if (++cnt[NHG_N_NONSTIFF] >= 6) {
    cnt[NHG_N_STIFF] = 0;
  }
}

/* bisection for the first theta in (lo, hi] with g(y(theta)) < tol, given g(y(lo)) >= tol */
static double nhg_locate(nhg_ctx *cx, const nhg_method *m, double t, double h, const double *y,
                         double R[][NHG_NY], double tol, double lo, double hi, double *y_event) {
  double ytmp[NHG_NY];
  int it;
  for (it = 0; it < 80 && (hi - lo) * fabs(h) > 4.0 * DBL_EPSILON * fmax(fabs(t), 1.0); ++it) {
    double mid = 0.5 * (lo + hi), g;
    nhg_dense(m, mid, y, R, ytmp);
    g = nhg_g(cx, ytmp, 0, 0);
    if (isfinite(g) && g >= tol) lo = mid;
    else hi = mid;
  }
  nhg_dense(m, hi, y, R, y_event);
  return hi;
}

/* minimum of g(y(theta)) on [lo, hi] by golden-section search; returns theta, g in *gmin */
static double nhg_golden(nhg_ctx *cx, const nhg_method *m, const double *y, double R[][NHG_NY],
                         double lo, double hi, double *gmin) {
  const double r = 0.6180339887498949;
  double ytmp[NHG_NY], a = hi - r * (hi - lo), b = lo + r * (hi - lo), ga, gb;
  int it;
  nhg_dense(m, a, y, R, ytmp);
  ga = nhg_g(cx, ytmp, 0, 0);
  nhg_dense(m, b, y, R, ytmp);
  gb = nhg_g(cx, ytmp, 0, 0);
  for (it = 0; it < 60 && hi - lo > 1e-13; ++it) {
    if (!(ga >= gb)) {           /* also when ga is NaN: keep the left part */
      hi = b; b = a; gb = ga;
      a = hi - r * (hi - lo);
      nhg_dense(m, a, y, R, ytmp);
      ga = nhg_g(cx, ytmp, 0, 0);
    } else {
      lo = a; a = b; ga = gb;
      b = lo + r * (hi - lo);
      nhg_dense(m, b, y, R, ytmp);
      gb = nhg_g(cx, ytmp, 0, 0);
    }
  }
  *gmin = fmin(ga, gb);
  return ga < gb ? a : b;
}

/* Event in the step? The measure is checked at the end point. It touches zero and rises again
   where a trajectory crosses the singular set (it is a squared quantity), so a step can jump
   over a crossing its end points do not show. When either end is within NHG_WATCH * tol of the
   threshold, or the measure can change by more than half its value within the step
   (h |dg/dt| > g / 2 at an end), it is sampled at 7 interior points of the continuous extension
   and every local minimum of the samples (and one next to an end where the end rate points
   down) is refined by golden-section search. Returns theta of the first point below tol
   (located by bisection) or -1; g and dg/dt at the end in g1_out, g1dot_out. */
#define NHG_WATCH 1e4
static double nhg_event_in_step(nhg_ctx *cx, const nhg_method *m, double t, double h,
                                const double *y, const double *y1, double k[][NHG_NY],
                                double R[][NHG_NY], int *dense_ready, double g0, double g0dot,
                                double tol, double *g1_out, double *g1dot_out, double *y_event) {
  double g1dot, g1 = nhg_g(cx, y1, k[m->i_new], &g1dot), gs[9], ytmp[NHG_NY], gmin;
  int j;
  *g1_out = g1;
  *g1dot_out = g1dot;
  gmin = fmin(g0, g1);
  if (isfinite(g1) && g1 >= tol && gmin >= NHG_WATCH * tol &&
      fabs(h) * fmax(fabs(g0dot), fabs(g1dot)) <= 0.5 * gmin) return -1.0;
  if (!*dense_ready) {
    nhg_prepare_dense(cx, m, t, h, y, k, R);
    *dense_ready = 1;
  }
  gs[0] = g0;
  gs[8] = g1;
  for (j = 1; j < 8; ++j) {
    nhg_dense(m, j / 8.0, y, R, ytmp);
    gs[j] = nhg_g(cx, ytmp, 0, 0);
  }
  for (j = 0; j <= 8; ++j) {        /* in theta order: a sample below tol, or a dip below it */
    double a, b, g, th;
    int dip;
    if (j > 0 && !(isfinite(gs[j]) && gs[j] >= tol))
      return nhg_locate(cx, m, t, h, y, R, tol, (j - 1) / 8.0, j / 8.0, y_event);
    if (j == 0) {                  /* falling at the start but up again at the first sample */
      dip = g0dot < 0.0 && gs[1] > gs[0];
      a = 0.0, b = 1.0 / 8.0;
    } else if (j < 8) {            /* a local minimum of the samples */
      dip = gs[j] <= gs[j - 1] && gs[j] <= gs[j + 1];
      a = (j - 1) / 8.0, b = (j + 1) / 8.0;
    } else {                       /* rising at the end but down from the last sample */
      dip = g1dot > 0.0 && gs[7] > gs[8];
      a = 7.0 / 8.0, b = 1.0;
    }
    if (!dip) continue;
    th = nhg_golden(cx, m, y, R, a, b, &g);
    if (!(isfinite(g) && g >= tol)) return nhg_locate(cx, m, t, h, y, R, tol, a, th, y_event);
  }
  return -1.0;
}

CASADI_SYMBOL_EXPORT int nhg_abi_version(void) { return 2; }
CASADI_SYMBOL_EXPORT int nhg_dims(int which) {
  return which == 0 ? NHG_NY : which == 1 ? NHG_NP : which == 2 ? NHG_NOUT : which == 3 ? NHG_HAS_EVENT
       : NHG_NDIAG;
}

/* Integrate from ctl[T] to t_end (the controller sees t clamped to t_hi). y: in/out (NHG_NY).
   t_eval (n_eval, increasing) with y_eval (n_eval x NHG_NY): outputs written from index
   cnt[IEVAL] on; or, with t_eval NULL, every accepted step into t_steps/y_steps (capacity cap,
   room for cap + 1 rows); with both NULL only the final state (in y). */
CASADI_SYMBOL_EXPORT int nhg_run(int method, double t_end, double t_hi, double *y,
                                 const double *p, double *ctl, long long *cnt,
                                 const double *t_eval, long long n_eval, double *y_eval,
                                 double *t_steps, double *y_steps, long long cap) {
  const nhg_method *m = &NHG_METHODS[method == 1 ? 1 : 0];
  nhg_ctx cx;
  double k[NHG_MAX_STAGES][NHG_NY], R[NHG_MAX_DEGREE][NHG_NY];
  double ytmp[NHG_NY], y1[NHG_NY], ystiff[NHG_NY], yev[NHG_NY];
  double t = ctl[NHG_C_T], h = ctl[NHG_C_H];
  double rtol = ctl[NHG_C_RTOL], atol = ctl[NHG_C_ATOL], hmax = ctl[NHG_C_HMAX];
  double evtol = ctl[NHG_C_EVTOL], err_old = ctl[NHG_C_ERROLD];
  double g_prev = 1.0, g_prev_dot = 0.0;
  int last_rejected = 0, trial_nonfinite = 0, i, bad;
  cx.p = p;
  cx.t_hi = t_hi;
  cx.nfev = &cnt[NHG_N_FEV];
  cnt[NHG_N_OUT] = 0;

  nhg_f(&cx, t, y, k[0]);
  bad = nhg_first_bad(k[0], NHG_NY);
  if (bad >= 0) {
    cnt[NHG_N_BAD] = bad;
    ctl[NHG_C_TFAIL] = t;
    return NHG_NONFINITE;
  }
  if (!(h > 0.0)) h = nhg_initial_step(&cx, m, t, y, k[0], rtol, atol, hmax, t_end - t);
  if (evtol > 0.0) g_prev = nhg_g(&cx, y, k[0], &g_prev_dot);

  while (t < t_end) {
    double err, t_new, hmin = 16.0 * DBL_EPSILON * fmax(fabs(t), DBL_MIN);
    int last = 0, dense_ready = 0, event = 0;
    double theta_ev = -1.0;
    if (cnt[NHG_N_ACC] >= cnt[NHG_N_MAXSTEPS]) {
      ctl[NHG_C_TFAIL] = t;
      ctl[NHG_C_T] = t;
      return NHG_MAX_STEPS;
    }
    if (h > hmax) h = hmax;
    if (t + h >= t_end) {
      h = t_end - t;
      last = 1;
    }
    for (i = 1; i < m->s_step; ++i) {
      nhg_stage_arg(m, i, h, y, k, ytmp);
      if (i == m->i_stiff) memcpy(ystiff, ytmp, sizeof ytmp);
      nhg_f(&cx, t + m->c[i] * h, ytmp, k[i]);
    }
    if (m->i_new < m->s_step) memcpy(y1, ytmp, sizeof ytmp);  /* FSAL: last stage is at y1 */
    else nhg_stage_arg(m, m->i_new, h, y, k, y1);
    err = nhg_error(m, h, y, y1, k, rtol, atol);

    if (!isfinite(err) || nhg_first_bad(y1, NHG_NY) >= 0) {     /* a stage left the domain */
      ++cnt[NHG_N_REJ];
      trial_nonfinite = 1;
      last_rejected = 1;
      h *= 0.25;
      if (h < hmin) {
        ctl[NHG_C_TFAIL] = t;
        ctl[NHG_C_T] = t;
        return NHG_NONFINITE_TRIAL;
      }
      continue;
    }
    if (err > 1.0) {                                            /* rejected */
      ++cnt[NHG_N_REJ];
      last_rejected = 1;
      h *= fmax(m->fac_min, m->safety * pow(err, -m->expo));
      if (h < hmin) {
        ctl[NHG_C_TFAIL] = t;
        ctl[NHG_C_T] = t;
        return trial_nonfinite ? NHG_NONFINITE_TRIAL : NHG_STEP_TOO_SMALL;
      }
      continue;
    }

    /* accepted */
    t_new = last ? t_end : t + h;
    ++cnt[NHG_N_ACC];
    if (m->i_new >= m->s_step) nhg_f(&cx, t_new, y1, k[m->i_new]);
    nhg_stiffness(m, h, y1, ystiff, k, ctl, cnt, t_new);
    if (evtol > 0.0) {
      double g1, g1dot;
      theta_ev = nhg_event_in_step(&cx, m, t, h, y, y1, k, R, &dense_ready, g_prev, g_prev_dot,
                                   evtol, &g1, &g1dot, yev);
      event = theta_ev > 0.0;
      ctl[NHG_C_GLAST] = g_prev = g1;
      g_prev_dot = g1dot;
    }
    {                                                           /* outputs in (t, t + theta h] */
      double t_stop = event ? t + theta_ev * h : t_new;
      if (t_eval) {
        long long j = cnt[NHG_N_IEVAL];
        while (j < n_eval && t_eval[j] <= t_stop) {
          if (t_eval[j] == t_new && !event) memcpy(&y_eval[j * NHG_NY], y1, sizeof y1);
          else {
            if (!dense_ready) {
              nhg_prepare_dense(&cx, m, t, h, y, k, R);
              dense_ready = 1;
            }
            nhg_dense(m, (t_eval[j] - t) / h, y, R, &y_eval[j * NHG_NY]);
          }
          nhg_proj(&cx, &y_eval[j * NHG_NY]);
          ++j;
        }
        cnt[NHG_N_IEVAL] = j;
      } else if (t_steps && !event) {
        t_steps[cnt[NHG_N_OUT]] = t_new;
        memcpy(&y_steps[cnt[NHG_N_OUT] * NHG_NY], y1, sizeof y1);
        nhg_proj(&cx, &y_steps[cnt[NHG_N_OUT] * NHG_NY]);
        ++cnt[NHG_N_OUT];
      }
    }
    if (event) {
      double t_ev = t + theta_ev * h;
      nhg_proj(&cx, yev);
      if (!t_eval && t_steps) {
        t_steps[cnt[NHG_N_OUT]] = t_ev;
        memcpy(&y_steps[cnt[NHG_N_OUT] * NHG_NY], yev, sizeof yev);
        ++cnt[NHG_N_OUT];
      }
      memcpy(y, yev, sizeof yev);
      ctl[NHG_C_T] = t_ev;
      ctl[NHG_C_TFAIL] = t_ev;
      return NHG_EVENT;
    }
    t = t_new;
    if (NHG_HAS_PROJECT) {
      nhg_proj(&cx, y1);
      nhg_f(&cx, t, y1, k[0]);
    } else {
      memcpy(k[0], k[m->i_new], sizeof k[0]);
    }
    memcpy(y, y1, sizeof y1);
    bad = nhg_first_bad(k[0], NHG_NY);
    if (bad >= 0) {
      cnt[NHG_N_BAD] = bad;
      ctl[NHG_C_TFAIL] = t;
      ctl[NHG_C_T] = t;
      return NHG_NONFINITE;
    }
    {                                                           /* next step size */
      double fac = err > 0.0 ? m->safety * pow(err, -m->expo) * pow(err_old, m->beta)
                             : m->fac_max;
      fac = fmin(m->fac_max, fmax(m->fac_min, fac));
      if (last_rejected) fac = fmin(fac, 1.0);
      h *= fac;
      err_old = fmax(err, 1e-4);
      last_rejected = 0;
      trial_nonfinite = 0;
    }
    ctl[NHG_C_T] = t;
    ctl[NHG_C_H] = h;
    ctl[NHG_C_ERROLD] = err_old;
    if (ctl[NHG_C_STOP_STIFF] != 0.0 && !isnan(ctl[NHG_C_TSTIFF])) return NHG_STIFF;
    if (!t_eval && t_steps && cnt[NHG_N_OUT] >= cap && t < t_end) return NHG_PAUSED;
  }
  ctl[NHG_C_T] = t;
  return NHG_DONE;
}

/* a generated function of (t, t_c, y, p) at N points: t, t_c (N), Y (N x NHG_NY), seg (N) the
   segment of each point, P (segments x NHG_NP) the parameter vector of each segment
   -> OUT (N x width) */
typedef int (*nhg_point_function)(const casadi_real **, casadi_real **, casadi_int *, casadi_real *, int);

static void nhg_at_points(nhg_point_function f, long long width, long long N, const double *t,
                          const double *tc, const double *Y, const long long *seg, const double *P,
                          double *OUT) {
  nhg_ctx cx;
  long long i;
  for (i = 0; i < N; ++i) {
    cx.arg[0] = &t[i];
    cx.arg[1] = &tc[i];
    cx.arg[2] = &Y[i * NHG_NY];
    cx.arg[3] = &P[seg[i] * NHG_NP];
    cx.res[0] = &OUT[i * width];
    f(cx.arg, cx.res, cx.iw, cx.w, 0);
  }
}

/* the outputs at N points (arguments as nhg_at_points) -> OUT (N x NHG_NOUT) */
CASADI_SYMBOL_EXPORT void nhg_outputs(long long N, const double *t, const double *tc,
                                      const double *Y, const long long *seg, const double *P,
                                      double *OUT) {
  nhg_at_points(nhg_out, NHG_NOUT, N, t, tc, Y, seg, P, OUT);
}

/* the diagnostic outputs at N points (arguments as nhg_at_points) -> OUT (N x NHG_NDIAG) */
CASADI_SYMBOL_EXPORT void nhg_diagnostics(long long N, const double *t, const double *tc,
                                          const double *Y, const long long *seg, const double *P,
                                          double *OUT) {
  nhg_at_points(nhg_diag, NHG_NDIAG, N, t, tc, Y, seg, P, OUT);
}

/* one right-hand-side evaluation (for tests and the per-evaluation benchmark): repeat times */
CASADI_SYMBOL_EXPORT void nhg_eval_rhs(double t, double t_hi, const double *y, const double *p,
                                       double *dy, long long repeat) {
  nhg_ctx cx;
  long long nfev = 0, r;
  cx.p = p;
  cx.t_hi = t_hi;
  cx.nfev = &nfev;
  for (r = 0; r < repeat; ++r) nhg_f(&cx, t, y, dy);
}
