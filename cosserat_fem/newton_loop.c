/* The inner loop of cosserat_fem/newton.py in C: the residual assembly of a DOLFINx form and
 * one modified-Newton iteration, for a serial run (cosserat_fem/native_newton.py builds it).
 *
 * cf_residual does what NewtonSolver._assemble does with DOLFINx 0.5.2's assemble_vector and
 * set_bc, in the same order of operations, so that b comes out bitwise the same: b = 0; for
 * each cell integral (in the form's order), for each cell of its domain (in order): w = the
 * packed coefficients, be = 0, the FFCx kernel, b[dofs] += be; then the exterior facet
 * integrals likewise with the cell's local facet index; then the Dirichlet rows
 * b[d] = -1 (g[d] - u[d]) (set_bc with scale -1). The coefficients are gathered through
 * index tables that native_newton.py reads off DOLFINx's own pack_coefficients, so any
 * coefficient the form has is packed as DOLFINx packs it.
 *
 * cf_iterate is one pass of NewtonSolver._run's loop body: KSPSolve(b, dx), the KSP's
 * reason, U -= dx, b = F(U), and the norms (||U||, ||dx||, ||b||) in one split-phase
 * reduction, as _norms takes them.
 *
 * cf_newton is the whole of NewtonSolver._run for a reused Jacobian and no per-iteration
 * observer: the first residual and its norm, the test at k = 0, then cf_iterate and the stop
 * rule of NewtonSolver._test (cf_test, which tests/unit/test_newton_stop.py feeds the same
 * sequences as the Python rule), in the same order and the same IEEE operations (compiled with
 * -ffp-contract=off: no fused multiply-adds). It returns to Python once, before the first
 * iteration, when the caller says a Jacobian is due (phase 1), and goes on when called again.
 */
#include <math.h>
#include <petscksp.h>
#include <petscsnes.h>
#include <stdint.h>
#include <string.h>
#include <time.h>

#include "ufcx.h"

typedef struct {
  void* kernel;                /* ufcx_tabulate_tensor_float64* */
  int32_t entities;            /* cells (or facets) of the integral's domain */
  const int32_t* cells;        /* (entities,) */
  const int32_t* local_facets; /* (entities,), NULL for a cell integral */
  int32_t wsize;               /* packed coefficient values per entity */
  const int32_t* source;       /* (wsize,) which coefficient each packed value comes from */
  const int32_t* index;        /* (entities, wsize) its index in that coefficient's array */
} cf_integral;

typedef struct {
  int32_t n_integrals;
  const cf_integral* integrals;
  double* const* coefficients; /* each coefficient's value array (DOLFINx Function.x.array) */
  const double* constants;     /* packed constants (pack_constants), refreshed by the caller */
  const double* coordinates;   /* (cells, coordinates_per_cell) */
  int32_t coordinates_per_cell;
  const int32_t* dofs;         /* (cells, dofs_per_cell): b's entries of a cell, block-unrolled */
  int32_t dofs_per_cell;
  int32_t n_bc;
  const int32_t* bc_dofs;      /* the Dirichlet dofs */
  const double* bc_values;     /* g at every dof (zero elsewhere), refreshed by the caller */
  const double* u_values;      /* U's values (the array the Vec u wraps) */
  double* w;                   /* scratch: the largest wsize */
  double* be;                  /* scratch: dofs_per_cell */
  void *u, *b, *dx, *ksp;      /* PETSc Vec and KSP */
  double time_residual;        /* s, accumulated */
  int64_t residuals;           /* assemblies, accumulated */
} cf_problem;

static double now(void)
{
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void assemble(const cf_problem* p, double* b)
{
  const int32_t nd = p->dofs_per_cell, nc = p->coordinates_per_cell;
  for (int32_t k = 0; k < p->n_integrals; ++k) {
    const cf_integral* in = &p->integrals[k];
    for (int32_t e = 0; e < in->entities; ++e) {
      const int32_t c = in->cells[e];
      const int32_t* index = in->index + (int64_t)e * in->wsize;
      for (int32_t j = 0; j < in->wsize; ++j)
        p->w[j] = p->coefficients[in->source[j]][index[j]];
      memset(p->be, 0, sizeof(double) * (size_t)nd);
      ufcx_tabulate_tensor_float64* kernel = (ufcx_tabulate_tensor_float64*)in->kernel;
      kernel(p->be, p->w, p->constants, p->coordinates + (int64_t)c * nc,
             in->local_facets ? &in->local_facets[e] : NULL, NULL);
      const int32_t* dofs = p->dofs + (int64_t)c * nd;
      for (int32_t i = 0; i < nd; ++i)
        b[dofs[i]] += p->be[i];
    }
  }
}

/* b = F(U) with the Dirichlet rows x - g; 0 or a PETSc error code. */
int cf_residual(cf_problem* p)
{
  const double t0 = now();
  PetscScalar* b;
  PetscInt n;
  PetscErrorCode ierr = VecGetLocalSize((Vec)p->b, &n);
  if (ierr) return (int)ierr;
  ierr = VecGetArray((Vec)p->b, &b);
  if (ierr) return (int)ierr;
  memset(b, 0, sizeof(double) * (size_t)n);
  assemble(p, b);
  for (int32_t i = 0; i < p->n_bc; ++i) {
    const int32_t d = p->bc_dofs[i];
    b[d] = -1.0 * (p->bc_values[d] - p->u_values[d]);
  }
  ierr = VecRestoreArray((Vec)p->b, &b);
  if (ierr) return (int)ierr;
  p->time_residual += now() - t0;
  p->residuals += 1;
  return 0;
}

/* One iteration from U with F(U) in b: *reason = the KSP's converged reason; when it is not
 * negative, U -= dx, b = F(U), norms = (||U||, ||dx||, ||b||). 0 or a PETSc error code. */
int cf_iterate(cf_problem* p, int* reason, double* norms)
{
  KSPConvergedReason r;
  PetscErrorCode ierr = KSPSolve((KSP)p->ksp, (Vec)p->b, (Vec)p->dx);
  if (ierr) return (int)ierr;
  ierr = KSPGetConvergedReason((KSP)p->ksp, &r);
  if (ierr) return (int)ierr;
  *reason = (int)r;
  if (r < 0) return 0;
  ierr = VecAXPY((Vec)p->u, -1.0, (Vec)p->dx);
  if (ierr) return (int)ierr;
  ierr = cf_residual(p);
  if (ierr) return ierr;
  PetscReal fnorm, ynorm, xnorm;
  if ((ierr = VecNormBegin((Vec)p->b, NORM_2, &fnorm))) return (int)ierr;
  if ((ierr = VecNormBegin((Vec)p->dx, NORM_2, &ynorm))) return (int)ierr;
  if ((ierr = VecNormBegin((Vec)p->u, NORM_2, &xnorm))) return (int)ierr;
  if ((ierr = VecNormEnd((Vec)p->b, NORM_2, &fnorm))) return (int)ierr;
  if ((ierr = VecNormEnd((Vec)p->dx, NORM_2, &ynorm))) return (int)ierr;
  if ((ierr = VecNormEnd((Vec)p->u, NORM_2, &xnorm))) return (int)ierr;
  norms[0] = xnorm;
  norms[1] = ynorm;
  norms[2] = fnorm;
  return 0;
}

/* The float64 kernel of the i-th integral of a type (0 cell, 1 exterior facet) of a ufcx_form
 * (its address, as DOLFINx's Form holds it), in the order of Form.integral_ids. */
void* cf_kernel(uintptr_t form, int type, int i)
{
  ufcx_integral** integrals = ((ufcx_form*)form)->integrals((ufcx_integral_type)type);
  return (void*)integrals[i]->tabulate_tensor_float64;
}

typedef struct {
  double rtol, atol, stol, xatol;
  int max_iterations;
  int linear_test;   /* a reused Jacobian: the contraction estimate of _test */
} cf_settings;

typedef struct {
  int phase;         /* 0: start a solve; 1: before the first iteration (a Jacobian is due) */
  int need_jacobian; /* in: the caller will assemble one before the first iteration */
  int iterations;
  int reason;        /* SNESConvergedReason */
  double f0, f_prev, update_prev;
  double norms[3];   /* the last (||U||, ||dx||, ||F||) */
} cf_newton_state;

/* NewtonSolver._test: the reason after iteration it with norms (||U||, ||dU||, ||F||), at
 * it = 0 (0, 0, ||F0||); keeps ||F0|| and the last ||dU||, ||F|| in st for the estimate. */
int cf_test(const cf_settings* s, cf_newton_state* st, int it, const double* n)
{
  const double xnorm = n[0], ynorm = n[1], fnorm = n[2];
  if (fnorm != fnorm || ynorm != ynorm) return SNES_DIVERGED_FNORM_NAN;
  if (it == 0) {
    st->f0 = st->f_prev = fnorm;
    return fnorm <= s->atol ? SNES_CONVERGED_FNORM_ABS : SNES_CONVERGED_ITERATING;
  }
  const int linear = it >= 2 && s->linear_test && st->update_prev > 0.0;
  double rho = 0.0;
  if (linear) {
    const double a = ynorm / st->update_prev, b = fnorm / st->f_prev;
    rho = b > a ? b : a; /* Python's max(a, b) */
  }
  st->update_prev = ynorm;
  st->f_prev = fnorm;
  if (fnorm <= s->atol) return SNES_CONVERGED_FNORM_ABS;
  if (fnorm <= s->rtol * st->f0) return SNES_CONVERGED_FNORM_RELATIVE;
  const double tolerance = s->stol * xnorm + s->xatol;
  if (ynorm <= tolerance || (linear && rho < 1.0 && ynorm * rho / (1.0 - rho) <= tolerance))
    return SNES_CONVERGED_SNORM_RELATIVE;
  if (it >= s->max_iterations) return SNES_DIVERGED_MAX_IT;
  return SNES_CONVERGED_ITERATING;
}

/* NewtonSolver._run (see the top of the file); 0 or a PETSc error code. */
int cf_newton(cf_problem* p, const cf_settings* s, cf_newton_state* st)
{
  int ierr;
  if (st->phase == 0) {
    PetscReal fnorm;
    st->iterations = 0;
    if ((ierr = cf_residual(p))) return ierr;
    if ((ierr = (int)VecNorm((Vec)p->b, NORM_2, &fnorm))) return ierr;
    if (!isfinite(fnorm)) {
      st->reason = SNES_DIVERGED_FNORM_NAN;
      return 0;
    }
    const double first[3] = {0.0, 0.0, fnorm};
    st->reason = cf_test(s, st, 0, first);
    if (st->reason == SNES_CONVERGED_ITERATING && s->max_iterations > 0 && st->need_jacobian) {
      st->phase = 1; /* the caller assembles the Jacobian and calls again */
      return 0;
    }
  }
  st->phase = 0;
  while (st->reason == SNES_CONVERGED_ITERATING && st->iterations < s->max_iterations) {
    int ksp_reason;
    if ((ierr = cf_iterate(p, &ksp_reason, st->norms))) return ierr;
    if (ksp_reason < 0) {
      st->reason = SNES_DIVERGED_LINEAR_SOLVE;
      break;
    }
    if (!isfinite(st->norms[2])) {
      st->reason = SNES_DIVERGED_FNORM_NAN;
      break;
    }
    st->iterations += 1;
    st->reason = cf_test(s, st, st->iterations, st->norms);
  }
  if (st->reason == SNES_CONVERGED_ITERATING) st->reason = SNES_DIVERGED_MAX_IT;
  return 0;
}

/* ---- A whole SDIRK step (cosserat_fem/integrators.py SDIRK.step with NewtonSolver.solve per
 * stage) and its accept, for a reused Jacobian: the stage values, the predictor, the solve
 * policy of NewtonSolver.solve (the lagged count, a retry with a fresh Jacobian, the frozen
 * refresh) and cf_newton per stage, with the same IEEE operations, element by element, as
 * the NumPy calls of the Python step. It returns to Python (CF_NEED_JACOBIAN) when a Jacobian
 * is due, and goes on from where it stopped when called again. */

#define CF_NEED_JACOBIAN (-1)
#define CF_MAX_STAGES 8

typedef struct {
  int32_t stages, n;
  double gamma;
  const double *A, *b, *c;      /* the tableau: (stages, stages), (stages,), (stages,) */
  double *u, *z, *u_n;          /* U, Z (Functions' arrays) and U_n, each (n,) */
  double *K, *taus;             /* this step's stage rates (stages, n) and their times */
  double *rates, *times;        /* the ring buffer of accepted stage rates (stages, n), times */
  double *guess, *term;         /* scratch (n,) */
  double* time_value;           /* the time Constant's own storage */
  double* constants;            /* the packed constants the residual reads */
  int32_t time_slot;            /* τ's index in them, -1 if the form has no τ */
  void* initial;                /* Vec: the stage's guess, kept for a retry */
  int lagged, lag, frozen, refresh_iterations; /* the Jacobian policy */
  /* in, per step */
  double h, time;
  int64_t stored;               /* stage rates stored so far (the ring's count) */
  /* the Newton policy's state, in and out */
  int need_jacobian, since;
  /* running: the stage and where in its solve (0 begin, 1 first run, 2 retry run) */
  int stage, phase, fresh, stage_iterations;
  /* out */
  double unknown_time;
  int iterations, reason;
  int64_t solves, newton_iterations, retries;
  int last_iterations, max_in_a_solve;
  double time_solve;
  /* loads given by data (cosserat_fem/load_coefficients.py), in: where each one's values go
   * (a slot of the packed constants, or a quadrature Function's array), how many, and their
   * values at every stage time of the step, (stages, data_stride), computed before it */
  int32_t n_data;
  double* const* data_targets;
  const int32_t* data_sizes;
  const double* data_values;
  int64_t data_stride;
} cf_sdirk;

/* SDIRK._rate_guess: the Lagrange extrapolation to tau of the newest stored rates known before
 * stage `stage` into sd->guess; 0 when there are none (the guess is then the number 0.0). */
static int rate_guess(cf_sdirk* sd, int stage, double tau)
{
  const int s = sd->stages, n = sd->n;
  const int64_t old = sd->stored < s - stage ? sd->stored : s - stage;
  int slots[CF_MAX_STAGES], m = 0;
  double later[2 * CF_MAX_STAGES], nodes[2 * CF_MAX_STAGES], w[2 * CF_MAX_STAGES];
  const double* rows[2 * CF_MAX_STAGES];
  int total = 0;
  for (int64_t j = 0; j < old; ++j) later[total++] = sd->times[(sd->stored - old + j) % s];
  for (int j = 0; j < stage; ++j) later[total++] = sd->taus[j];
  for (int64_t j = 0; j < old; ++j) {
    const int slot = (int)((sd->stored - old + j) % s);
    int repeated = 0;
    for (int k = (int)j + 1; k < total; ++k)
      if (sd->times[slot] == later[k]) repeated = 1;
    if (!repeated) slots[m++] = slot;
  }
  if (!m && !stage) return 0;
  int count = 0;
  for (int j = 0; j < m; ++j) {
    nodes[count] = sd->times[slots[j]];
    rows[count++] = sd->rates + (int64_t)slots[j] * n;
  }
  for (int j = 0; j < stage; ++j) {
    nodes[count] = sd->taus[j];
    rows[count++] = sd->K + (int64_t)j * n;
  }
  for (int j = 0; j < count; ++j) { /* adaptive.lagrange_weight_list */
    double wj = 1.0;
    for (int k = 0; k < count; ++k)
      if (k != j) wj *= (tau - nodes[k]) / (nodes[j] - nodes[k]);
    w[j] = wj;
  }
  double* out = sd->guess;
  for (int32_t k = 0; k < n; ++k) out[k] = rows[0][k] * w[0];
  for (int j = 1; j < count; ++j)
    for (int32_t k = 0; k < n; ++k) out[k] += rows[j][k] * w[j];
  return 1;
}

/* The start of stage i: Z_i, the time τ_i (the Constant and the packed constants), the loads
 * given by data at τ_i, and the predicted U = guess γh + Z_i. */
static void stage_begin(cf_sdirk* sd, int i)
{
  const int n = sd->n;
  const double h = sd->h, gh = sd->gamma * h;
  for (int32_t k = 0; k < n; ++k) sd->z[k] = sd->u_n[k];
  for (int j = 0; j < i; ++j) {
    const double f = h * sd->A[i * sd->stages + j];
    const double* Kj = sd->K + (int64_t)j * n;
    for (int32_t k = 0; k < n; ++k) sd->z[k] += Kj[k] * f;
  }
  const double tau = sd->time + sd->c[i] * h;
  *sd->time_value = tau;
  if (sd->time_slot >= 0) sd->constants[sd->time_slot] = tau;
  sd->unknown_time = tau;
  if (sd->n_data > 0) { /* the loads given by data, at τ */
    const double* values = sd->data_values + (int64_t)i * sd->data_stride;
    for (int32_t k = 0; k < sd->n_data; ++k)
      for (int32_t j = 0; j < sd->data_sizes[k]; ++j) sd->data_targets[k][j] = *values++;
  }
  if (rate_guess(sd, i, tau)) {
    for (int32_t k = 0; k < n; ++k) sd->u[k] = sd->guess[k] * gh;
  } else {
    const double zero = 0.0 * gh;
    for (int32_t k = 0; k < n; ++k) sd->u[k] = zero;
  }
  for (int32_t k = 0; k < n; ++k) sd->u[k] += sd->z[k];
}

/* cf_newton from its phase, timed into sd->time_solve; its iterations counted. */
static int run_newton(cf_problem* p, const cf_settings* s, cf_newton_state* st, cf_sdirk* sd)
{
  const double t0 = now();
  const int ierr = cf_newton(p, s, st);
  sd->time_solve += now() - t0;
  if (!ierr && st->phase == 0) {
    sd->newton_iterations += st->iterations;
    sd->stage_iterations += st->iterations;
  }
  return ierr;
}

/* The SDIRK step of h from sd->time (sd->stage = 0, sd->phase = 0 to begin): 0 when done, with
 * sd->reason > 0 (U = U_n + h Σ b_i K_i) or <= 0 (the solve of stage sd->stage failed after
 * sd->stage_iterations iterations); CF_NEED_JACOBIAN when a Jacobian is due (the caller
 * assembles it, clears need_jacobian and since, and calls again); or a PETSc error code. */
int cf_sdirk_step(cf_problem* p, const cf_settings* s, cf_newton_state* st, cf_sdirk* sd)
{
  const int n = sd->n;
  const double h = sd->h, gh = sd->gamma * h;
  int ierr;
  if (sd->stages < 1 || sd->stages > CF_MAX_STAGES) return PETSC_ERR_ARG_OUTOFRANGE;
  while (sd->stage < sd->stages) {
    const int i = sd->stage;
    if (sd->phase == 0) { /* NewtonSolver.solve up to its first _run */
      stage_begin(sd, i);
      if (sd->lagged && sd->since >= sd->lag) sd->need_jacobian = 1;
      if ((ierr = (int)VecCopy((Vec)p->u, (Vec)sd->initial))) return ierr;
      sd->fresh = sd->need_jacobian;
      sd->stage_iterations = 0;
      sd->phase = 1;
      st->phase = 0;
      st->need_jacobian = sd->need_jacobian;
    } else {
      st->need_jacobian = sd->need_jacobian; /* 0: the caller assembled it */
    }
    if ((ierr = run_newton(p, s, st, sd))) return ierr;
    if (st->phase == 1) return CF_NEED_JACOBIAN;
    if (st->reason <= 0 && sd->phase == 1 && !sd->fresh) { /* retry with a new Jacobian */
      sd->retries += 1;
      if ((ierr = (int)VecCopy((Vec)sd->initial, (Vec)p->u))) return ierr;
      sd->need_jacobian = 1;
      sd->phase = 2;
      st->phase = 0;
      st->need_jacobian = 1;
      if ((ierr = run_newton(p, s, st, sd))) return ierr;
      if (st->phase == 1) return CF_NEED_JACOBIAN;
    }
    /* the rest of NewtonSolver.solve */
    sd->since += 1;
    sd->solves += 1;
    sd->last_iterations = sd->stage_iterations;
    if (sd->stage_iterations > sd->max_in_a_solve) sd->max_in_a_solve = sd->stage_iterations;
    sd->phase = 0;
    if (st->reason <= 0) {
      sd->reason = st->reason;
      return 0;
    }
    if (sd->frozen && sd->stage_iterations > sd->refresh_iterations) sd->need_jacobian = 1;
    sd->iterations += sd->stage_iterations;
    double* Ki = sd->K + (int64_t)i * n;
    const double inv = 1.0 / gh;
    for (int32_t k = 0; k < n; ++k) Ki[k] = sd->u[k] - sd->z[k];
    for (int32_t k = 0; k < n; ++k) Ki[k] *= inv;
    sd->taus[i] = sd->unknown_time;
    sd->stage += 1;
  }
  for (int32_t k = 0; k < n; ++k) sd->u[k] = sd->u_n[k];
  for (int i = 0; i < sd->stages; ++i) {
    const double f = h * sd->b[i];
    const double* Ki = sd->K + (int64_t)i * n;
    for (int32_t k = 0; k < n; ++k) sd->u[k] += Ki[k] * f;
  }
  sd->reason = st->reason;
  return 0;
}

/* SDIRK.accept's arrays: U_n = U, this step's stage rates and times into the ring buffer. */
void cf_sdirk_accept(cf_sdirk* sd)
{
  const int n = sd->n, s = sd->stages;
  memcpy(sd->u_n, sd->u, sizeof(double) * (size_t)n);
  for (int i = 0; i < s; ++i) {
    const int slot = (int)(sd->stored % s);
    memcpy(sd->rates + (int64_t)slot * n, sd->K + (int64_t)i * n, sizeof(double) * (size_t)n);
    sd->times[slot] = sd->taus[i];
    sd->stored += 1;
  }
}
