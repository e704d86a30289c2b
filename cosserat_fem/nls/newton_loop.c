/* Newton's method of cosserat_fem/nls/newton.py, written once, in C (cosserat_fem/nls/native_newton.py
 * builds it): the solve's Jacobian policy, the loop and the stop rule (cf_solve, cf_test), with
 * callbacks for what Python keeps (DOLFINx's residual assembly under MPI, the Jacobian, an
 * observer of the iterations, SNES's iterations); the residual assembly of a DOLFINx form for a
 * serial run (cf_residual); and the arithmetic kernels of an SDIRK step (cf_sdirk_*).
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
 * cf_solve is NewtonSolver.solve: the policy (a lagged Jacobian's count, one retry from the same
 * guess with a fresh Jacobian after a failure with an old one, the frozen refresh), then the
 * iterations of SNES newtonls with the basic line search: the first residual and its norm, the
 * test at k = 0, then per iteration the Jacobian if due, KSPSolve(b, dx), the KSP's reason,
 * U -= dx, b = F(U), the norms (||U||, ||dx||, ||b||) in one split-phase reduction, and the
 * stop rule cf_test (tests/unit/test_newton_stop.py), compiled with -ffp-contract=off (no fused
 * multiply-adds). Each callback returns 0 or a nonzero status (a PETSc error code, or
 * CF_CALLBACK_ERROR when Python stored an exception), which ends the solve at once and is
 * cf_solve's answer.
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
  const double* weights;       /* (entities,) ECSW weights xi_e of a sampled integral, or NULL */
} cf_integral;

typedef struct {
  int32_t n_integrals;
  const cf_integral* integrals;
  double* const* coefficients; /* each coefficient's value array (DOLFINx Function.x.array) */
  int32_t n_constants;
  double* const* constant_values; /* each Constant's own storage, in the form's order */
  const int32_t* constant_sizes;  /* and its size */
  double* constants;           /* the packed constants: gathered from them at each residual */
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
  void* b;                     /* the PETSc Vec F(U) goes into */
  int32_t n_ties;              /* dofs identified by rows (cosserat_fem/nls/constraints.py) */
  const int32_t* tie_copies;   /* (n_ties,) each pair's copy */
  const int32_t* tie_masters;  /* (n_ties,) and master */
  const int32_t* tie_added;    /* (n_ties,) 1: the master's row takes the copy's (C.1) */
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

/* b = F(U) with the Dirichlet rows x - g and the identified dofs' rows; 0 or a PETSc error
 * code. */
int cf_residual(cf_problem* p)
{
  PetscScalar* b;
  PetscInt n;
  PetscErrorCode ierr = VecGetLocalSize((Vec)p->b, &n);
  if (ierr) return (int)ierr;
  ierr = VecGetArray((Vec)p->b, &b);
  if (ierr) return (int)ierr;
  memset(b, 0, sizeof(double) * (size_t)n);
  double* packed = p->constants; /* pack_constants: the values one Constant after the other */
  for (int32_t k = 0; k < p->n_constants; ++k)
    for (int32_t j = 0; j < p->constant_sizes[k]; ++j) *packed++ = p->constant_values[k][j];
  assemble(p, b);
  for (int32_t i = 0; i < p->n_bc; ++i) {
    const int32_t d = p->bc_dofs[i];
    b[d] = -1.0 * (p->bc_values[d] - p->u_values[d]);
  }
  /* Identification.apply_vector's (C.1)-(C.2), in its order: the same bits */
  for (int32_t i = 0; i < p->n_ties; ++i)
    if (p->tie_added[i]) b[p->tie_masters[i]] += b[p->tie_copies[i]];
  for (int32_t i = 0; i < p->n_ties; ++i) {
    const int32_t c = p->tie_copies[i];
    b[c] = p->u_values[c] - p->u_values[p->tie_masters[i]];
  }
  ierr = VecRestoreArray((Vec)p->b, &b);
  return (int)ierr;
}

/* The float64 kernel of the i-th integral of a type (0 cell, 1 exterior facet) of a ufcx_form
 * (its address, as DOLFINx's Form holds it), in the order of Form.integral_ids. */
void* cf_kernel(uintptr_t form, int type, int i)
{
  ufcx_integral** integrals = ((ufcx_form*)form)->integrals((ufcx_integral_type)type);
  return (void*)integrals[i]->tabulate_tensor_float64;
}


#define CF_CALLBACK_ERROR (-2)

typedef int (*cf_call)(void* ctx);                 /* b = F(U), or A = J(U) */
typedef int (*cf_observe)(void* ctx, int it, const double* norms, int reason);
typedef int (*cf_run)(void* ctx, int* iterations, int* reason); /* SNES's iterations */
typedef int (*cf_guess)(void* ctx, int restore); /* keep (0) or restore (1) the guess */

typedef struct {
  double rtol, atol, stol, xatol;
  int max_iterations;
  int linear_test;   /* a reused Jacobian: the contraction estimate of the stop rule */
  int full, lagged, lag, frozen, refresh_iterations; /* the Jacobian policy */
} cf_settings;

typedef struct {
  cf_problem* problem;    /* the C assembler, or NULL: the residual callback */
  cf_call residual, jacobian;
  cf_observe on_iteration; /* NULL unless an observer listens */
  cf_run run;             /* NULL: Newton's loop here; else the iterations of SNES */
  void* ctx;              /* the callbacks' argument */
  void *u, *b, *dx, *ksp, *initial; /* PETSc Vec and KSP; initial: the guess, for a retry */
  cf_guess guess;         /* NULL: the guess kept in initial; else kept by this (a reduced
                           * unknown's coordinates, docs/rom.md §8) */
} cf_solver;

typedef struct {
  double f0, f_prev, update_prev; /* the stop rule's running norms */
  double norms[3];     /* the last (||U||, ||dx||, ||F||) */
  int need_jacobian, since; /* the policy: a Jacobian is due; solves since the last one */
  int iterations, reason;   /* of the last solve (retry included); SNESConvergedReason */
  /* counters, accumulated */
  int64_t solves, newton_iterations, retries, residuals;
  int last_iterations, max_in_a_solve;
  double time_solve, time_residual; /* s */
  int hold;  /* 1: the last residual changed rows it replaces (an active set): not converged */
  int guard; /* 1: the update test also needs ||F|| <= ||F0|| (a drift of a mechanism that an
              * active set leaves, whose updates shrink relative to a growing U, is no answer) */
} cf_newton_state;

static int rule(const cf_settings* s, cf_newton_state* st, int it, const double* n);

/* The stop rule: the reason after iteration it with norms (||U||, ||dU||, ||F||), at it = 0
 * (0, 0, ||F0||); keeps ||F0|| and the last ||dU||, ||F|| in st for the estimate. While
 * st->hold is set (the residual's rows changed with its iterate: a contact's active set,
 * cosserat_fem/nls/contact.py) a solve is not converged: it goes on, or ends at the
 * iteration limit; with st->guard the update test stops it only with ||F|| <= ||F0||. */
int cf_test(const cf_settings* s, cf_newton_state* st, int it, const double* n)
{
  const int reason = rule(s, st, it, n);
  const int unsettled = st->hold || (st->guard && reason == SNES_CONVERGED_SNORM_RELATIVE &&
                                     !(n[2] <= st->f0));
  if (!unsettled || reason <= 0) return reason;
  return it >= s->max_iterations ? SNES_DIVERGED_MAX_IT : SNES_CONVERGED_ITERATING;
}

static int rule(const cf_settings* s, cf_newton_state* st, int it, const double* n)
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
    rho = b > a ? b : a; /* the larger ratio */
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

/* b = F(U): the C assembler or the callback, counted and timed. */
static int residual(const cf_solver* sv, cf_newton_state* st)
{
  const double t0 = now();
  const int ierr = sv->problem ? cf_residual(sv->problem) : sv->residual(sv->ctx);
  st->time_residual += now() - t0;
  st->residuals += 1;
  return ierr;
}

/* The stop rule, and the observer if there is one: 0 or the observer's status. */
static int test(const cf_solver* sv, const cf_settings* s, cf_newton_state* st, int it,
                const double* norms, int* reason)
{
  *reason = cf_test(s, st, it, norms);
  return sv->on_iteration ? sv->on_iteration(sv->ctx, it, norms, *reason) : 0;
}

/* Newton's iterations from U (SNES newtonls with the basic line search): *iterations and the
 * *reason; 0 or a PETSc error code or a callback's status. */
static int newton(const cf_solver* sv, const cf_settings* s, cf_newton_state* st,
                  int* iterations, int* reason)
{
  int ierr, it = 0;
  PetscReal fnorm;
  *iterations = 0;
  if ((ierr = residual(sv, st))) return ierr;
  if ((ierr = (int)VecNorm((Vec)sv->b, NORM_2, &fnorm))) return ierr;
  if (!isfinite(fnorm)) {
    *reason = SNES_DIVERGED_FNORM_NAN;
    return 0;
  }
  const double first[3] = {0.0, 0.0, fnorm};
  if ((ierr = test(sv, s, st, 0, first, reason))) return ierr;
  while (*reason == SNES_CONVERGED_ITERATING && it < s->max_iterations) {
    if (st->need_jacobian || s->full) {
      if ((ierr = sv->jacobian(sv->ctx))) return ierr;
      st->need_jacobian = 0;
      st->since = 0;
    }
    KSPConvergedReason r;
    if ((ierr = (int)KSPSolve((KSP)sv->ksp, (Vec)sv->b, (Vec)sv->dx))) return ierr;
    if ((ierr = (int)KSPGetConvergedReason((KSP)sv->ksp, &r))) return ierr;
    if (r < 0) {
      *reason = SNES_DIVERGED_LINEAR_SOLVE;
      break;
    }
    if ((ierr = (int)VecAXPY((Vec)sv->u, -1.0, (Vec)sv->dx))) return ierr;
    if ((ierr = residual(sv, st))) return ierr;
    PetscReal f, y, x;
    if ((ierr = (int)VecNormBegin((Vec)sv->b, NORM_2, &f))) return ierr;
    if ((ierr = (int)VecNormBegin((Vec)sv->dx, NORM_2, &y))) return ierr;
    if ((ierr = (int)VecNormBegin((Vec)sv->u, NORM_2, &x))) return ierr;
    if ((ierr = (int)VecNormEnd((Vec)sv->b, NORM_2, &f))) return ierr;
    if ((ierr = (int)VecNormEnd((Vec)sv->dx, NORM_2, &y))) return ierr;
    if ((ierr = (int)VecNormEnd((Vec)sv->u, NORM_2, &x))) return ierr;
    st->norms[0] = x;
    st->norms[1] = y;
    st->norms[2] = f;
    if (!isfinite(f)) {
      *reason = SNES_DIVERGED_FNORM_NAN;
      break;
    }
    it += 1;
    *iterations = it;
    if ((ierr = test(sv, s, st, it, st->norms, reason))) return ierr;
  }
  if (*reason == SNES_CONVERGED_ITERATING) *reason = SNES_DIVERGED_MAX_IT;
  return 0;
}

/* One run of iterations (Newton's here, or SNES's through sv->run), counted. */
static int iterate(const cf_solver* sv, const cf_settings* s, cf_newton_state* st, int* it,
                   int* reason)
{
  const int ierr = sv->run ? sv->run(sv->ctx, it, reason) : newton(sv, s, st, it, reason);
  st->newton_iterations += *it;
  return ierr;
}

/* NewtonSolver.solve from U (the guess): the Jacobian policy, the iterations, one retry from
 * the same guess with a fresh Jacobian if the solve failed with an old one, the counters. The
 * outcome is st->reason (> 0 converged) after st->iterations; the answer is 0, or a PETSc
 * error code or a callback's status (the solve then ended where it was). */
int cf_solve(const cf_solver* sv, const cf_settings* s, cf_newton_state* st)
{
  const double t0 = now();
  int ierr, iterations = 0, reason = SNES_CONVERGED_ITERATING;
  if (s->lagged && st->since >= s->lag) st->need_jacobian = 1;
  if (sv->guess) {
    if ((ierr = sv->guess(sv->ctx, 0))) return ierr;
  } else if ((ierr = (int)VecCopy((Vec)sv->u, (Vec)sv->initial)))
    return ierr;
  const int fresh = st->need_jacobian || s->full;
  ierr = iterate(sv, s, st, &iterations, &reason);
  if (!ierr && reason <= 0 && !fresh) { /* an old Jacobian may be the cause */
    int more = 0;
    st->retries += 1;
    if (sv->guess) {
      if ((ierr = sv->guess(sv->ctx, 1))) return ierr;
    } else if ((ierr = (int)VecCopy((Vec)sv->initial, (Vec)sv->u)))
      return ierr;
    st->need_jacobian = 1;
    ierr = iterate(sv, s, st, &more, &reason);
    iterations += more;
  }
  st->time_solve += now() - t0;
  if (ierr) return ierr;
  st->since += 1;
  st->solves += 1;
  st->iterations = iterations;
  st->reason = reason;
  st->last_iterations = iterations;
  if (iterations > st->max_in_a_solve) st->max_in_a_solve = iterations;
  if (reason > 0 && s->frozen && iterations > s->refresh_iterations) st->need_jacobian = 1;
  return 0;
}

/* ---- The arithmetic of an SDIRK step (cosserat_fem/timestepping/integrators.py SDIRK.step, which calls
 * these kernels around each stage's Newton solve, and SDIRK.accept): elementwise on the local
 * arrays (ghosts included), so they need no communication under MPI. */

#define CF_MAX_STAGES 8

typedef struct {
  int32_t stages, n;
  double gamma;
  const double *A, *b, *c;      /* the tableau: (stages, stages), (stages,), (stages,) */
  double *u, *z, *u_n;          /* U, Z (Functions' arrays) and U_n, each (n,) */
  double *K, *taus;             /* this step's stage rates (stages, n) and their times */
  double *rates, *times;        /* the ring buffer of accepted stage rates (stages, n), times */
  double* guess;                /* scratch (n,) */
  double* time_value;           /* the time Constant's own storage */
  int32_t predict;              /* cf_sdirk_stage makes the predictor's guess (else Python) */
  /* in, per step */
  double h, time;
  int64_t stored;               /* stage rates stored so far (the ring's count) */
  /* out: the time of the current stage's unknown */
  double unknown_time;
} cf_sdirk;

/* The Lagrange extrapolation to tau of the newest stored rates known before stage `stage`
 * into sd->guess (a stored rate whose time repeats a newer one's is left out); 0 when there
 * are none (the guess is then the number 0.0). */
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
  for (int j = 0; j < count; ++j) { /* the Lagrange weights of the nodes at tau */
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

/* The predictor of stage i (after its Z_i and tau_i are set): U = gamma h K~_i + Z_i, K~_i the rates'
 * extrapolation to tau_i (0 with none). */
void cf_sdirk_predict(cf_sdirk* sd, int i)
{
  const int n = sd->n;
  const double gh = sd->gamma * sd->h;
  if (rate_guess(sd, i, sd->unknown_time)) {
    for (int32_t k = 0; k < n; ++k) sd->u[k] = sd->guess[k] * gh;
  } else {
    const double zero = 0.0 * gh;
    for (int32_t k = 0; k < n; ++k) sd->u[k] = zero;
  }
  for (int32_t k = 0; k < n; ++k) sd->u[k] += sd->z[k];
}

/* Between the stages of a step: with 0 < i, the end of stage i - 1 (its solve converged):
 * K_{i-1} = (U - Z_{i-1}) (1/(gamma h)) and its time; then, with i < stages, the start of stage i:
 * Z_i = U_n + h sum_{j<i} a_ij K_j, the time tau_i = tau_n + c_i h (into the time Constant and
 * sd->unknown_time) and, if sd->predict, the predictor's guess U = gamma h K~_i + Z_i (K~_i the
 * stored rates' extrapolation to tau_i, 0 with none); with i == stages, U = U_n + h sum_i b_i K_i.
 * At most CF_MAX_STAGES stages (SDIRK's constructor checks). */
void cf_sdirk_stage(cf_sdirk* sd, int i)
{
  const int n = sd->n;
  const double h = sd->h, gh = sd->gamma * h;
  if (i > 0) {
    const double inv = 1.0 / gh;
    double* K = sd->K + (int64_t)(i - 1) * n;
    for (int32_t k = 0; k < n; ++k) K[k] = sd->u[k] - sd->z[k];
    for (int32_t k = 0; k < n; ++k) K[k] *= inv;
    sd->taus[i - 1] = sd->unknown_time;
  }
  if (i == sd->stages) {
    for (int32_t k = 0; k < n; ++k) sd->u[k] = sd->u_n[k];
    for (int j = 0; j < sd->stages; ++j) {
      const double f = h * sd->b[j];
      const double* Kj = sd->K + (int64_t)j * n;
      for (int32_t k = 0; k < n; ++k) sd->u[k] += Kj[k] * f;
    }
    return;
  }
  for (int32_t k = 0; k < n; ++k) sd->z[k] = sd->u_n[k];
  for (int j = 0; j < i; ++j) {
    const double f = h * sd->A[i * sd->stages + j];
    const double* Kj = sd->K + (int64_t)j * n;
    for (int32_t k = 0; k < n; ++k) sd->z[k] += Kj[k] * f;
  }
  const double tau = sd->time + sd->c[i] * h;
  *sd->time_value = tau;
  sd->unknown_time = tau;
  if (sd->predict) cf_sdirk_predict(sd, i);
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


/* ---- The hyper-reduced Newton iteration (cosserat_fem/rom/hyper.py; docs/rom.md (5), (9)-(11)).
 * The state is U = U_ref + V q, V (n, m) row-major; the reduced residual and Jacobian are sums
 * over the sampled entities of the integrals (cells E and their facets), each scaled by its
 * weight xi_e:
 *   r = sum_e xi_e (D V)_e^T F_e(U_e),   J_r = sum_e xi_e (D V)_e^T J_e(U_e) V_e,
 * with U_e = U_ref,e + V_e q written only into the entries of U the sampled entities read
 * (rows). Rows of Dirichlet dofs have V = D V = 0: their element entries add nothing, as the
 * full residual's rows x - g and the Jacobian's identity rows add nothing to V^T F, V^T J V.
 * cf_reduced_run is a cf_run: cf_solve keeps the policy (the need for a Jacobian, the retry,
 * the frozen refresh), this is one run of iterations with the same stop rule cf_test on
 * (||U||, ||V dq||, ||r||), 2-norms of the full vectors computed from the Gram matrix G = V^T V,
 * g = V^T U_ref, c = ||U_ref||^2 (no O(n) work in an iteration). Its only O(n) work is per
 * solve: U = U_ref + V q at the end on the rows the iterations did not write (the
 * integrator's state is the full vector), and the W-projection of a guess off the basis
 * (project). */

typedef struct {
  int32_t n, m;                      /* owned rows of U, reduced unknowns (2k) */
  const double *V, *DV, *WV, *ref;   /* (n, m), (n, m), (n, m), (n,) */
  const double *G, *g;               /* (m, m), (m,) */
  double c;                          /* ||U_ref||^2 */
  int32_t n_rows;
  const int32_t* rows;               /* the entries of U the sampled entities read */
  int32_t n_rest;
  const int32_t* rest;               /* the others: written at the end of a run only */
  int32_t n_fit;                     /* rows S of the guess's cheap projection, or 0 */
  const int32_t* fit;                /* S (among rows) */
  const double* P;                   /* (m, n_fit) the pseudo-inverse of V's rows S */
  int32_t project_all;               /* 1: the next guess is projected with W on every row */
  cf_problem *F, *J;                 /* sampled residual and Jacobian problems (be: nd, nd*nd) */
  const cf_settings* s;
  cf_newton_state* st;
  const cf_solver* solver;           /* its on_iteration, if set, is called with observer */
  void* observer;
  double *q, *r, *dq, *Jr, *lu, *work; /* (m), (m), (m), (m, m), (m, m), (nd, m) */
  int32_t* piv;                      /* (m) */
  int32_t factored;                  /* 1 when lu holds J_r's factors */
  int64_t jacobians, full_projections; /* counters */
  double time_jacobian;
  /* Reduced coordinates (docs/rom.md §8): the integrator's state is q itself and the
   * coordinates of its other Functions (SDIRK's Z); each solve starts from q as the
   * integrator left it, writes those Functions on `rows` only, and leaves the other rows of
   * U as they are (lifted by the caller where needed). */
  int32_t coordinates;               /* 1: this mode; 0: U is the integrator's full state */
  int32_t n_lifts;
  double* const* lift_values;        /* each Function's value array */
  double* const* lift_coords;        /* its coordinates (m,) */
  const double* lift_affine;         /* 1: U_ref + V c (a state); 0: V c (a rate) */
  double* q0;                        /* (m) the guess, kept for a retry */
  const double* VT;                  /* (m, n_rows) V's rows `rows`, transposed */
  double* t;                         /* scratch (n_rows) */
} cf_reduced;

static void packed_constants(cf_problem* p)
{
  double* packed = p->constants;
  for (int32_t k = 0; k < p->n_constants; ++k)
    for (int32_t j = 0; j < p->constant_sizes[k]; ++j) *packed++ = p->constant_values[k][j];
}

/* The element tensor of entity e of integral `in` into p->be (weights not applied). */
static void element(const cf_problem* p, const cf_integral* in, int32_t e, int32_t size)
{
  const int32_t c = in->cells[e];
  const int32_t* index = in->index + (int64_t)e * in->wsize;
  for (int32_t j = 0; j < in->wsize; ++j) p->w[j] = p->coefficients[in->source[j]][index[j]];
  memset(p->be, 0, sizeof(double) * (size_t)size);
  ufcx_tabulate_tensor_float64* kernel = (ufcx_tabulate_tensor_float64*)in->kernel;
  kernel(p->be, p->w, p->constants, p->coordinates + (int64_t)c * p->coordinates_per_cell,
         in->local_facets ? &in->local_facets[e] : NULL, NULL);
}

/* r = sum_e xi_e (D V)_e^T F_e; with `cells` (entities' cell -> row of out, (cells, m)) each
 * entity's projected vector is added to its cell's row instead (ECSW's training matrix). */
int cf_reduced_residual(cf_problem* p, const double* DV, int32_t m, double* r, double* out)
{
  const int32_t nd = p->dofs_per_cell;
  packed_constants(p);
  if (r) memset(r, 0, sizeof(double) * (size_t)m);
  for (int32_t k = 0; k < p->n_integrals; ++k) {
    const cf_integral* in = &p->integrals[k];
    for (int32_t e = 0; e < in->entities; ++e) {
      element(p, in, e, nd);
      const double xi = in->weights ? in->weights[e] : 1.0;
      const int32_t* dofs = p->dofs + (int64_t)in->cells[e] * nd;
      double* target = out ? out + (int64_t)in->cells[e] * m : r;
      for (int32_t i = 0; i < nd; ++i) {
        const double v = xi * p->be[i];
        const double* row = DV + (int64_t)dofs[i] * m;
        for (int32_t j = 0; j < m; ++j) target[j] += row[j] * v;
      }
    }
  }
  return 0;
}

/* J_r = sum_e xi_e (D V)_e^T J_e V_e ((m, m) row-major); work: (nd, m). */
int cf_reduced_jacobian(cf_problem* p, const double* DV, const double* V, int32_t m, double* Jr,
                        double* work)
{
  const int32_t nd = p->dofs_per_cell;
  packed_constants(p);
  memset(Jr, 0, sizeof(double) * (size_t)m * (size_t)m);
  for (int32_t k = 0; k < p->n_integrals; ++k) {
    const cf_integral* in = &p->integrals[k];
    for (int32_t e = 0; e < in->entities; ++e) {
      element(p, in, e, nd * nd);
      const double xi = in->weights ? in->weights[e] : 1.0;
      const int32_t* dofs = p->dofs + (int64_t)in->cells[e] * nd;
      /* work = A_e V_e (A_e row-major: test i, trial l) */
      memset(work, 0, sizeof(double) * (size_t)nd * (size_t)m);
      for (int32_t i = 0; i < nd; ++i) {
        double* wi = work + (int64_t)i * m;
        for (int32_t l = 0; l < nd; ++l) {
          const double a = p->be[(int64_t)i * nd + l];
          if (a == 0.0) continue;
          const double* vl = V + (int64_t)dofs[l] * m;
          for (int32_t j = 0; j < m; ++j) wi[j] += a * vl[j];
        }
      }
      for (int32_t i = 0; i < nd; ++i) {
        const double* di = DV + (int64_t)dofs[i] * m;
        const double* wi = work + (int64_t)i * m;
        for (int32_t a = 0; a < m; ++a) {
          const double d = xi * di[a];
          if (d == 0.0) continue;
          double* Ja = Jr + (int64_t)a * m;
          for (int32_t j = 0; j < m; ++j) Ja[j] += d * wi[j];
        }
      }
    }
  }
  return 0;
}

/* LU with partial pivoting of the (m, m) matrix a in place; 0, or 1 at a zero pivot. */
static int lu_factor(double* a, int32_t* piv, int32_t m)
{
  for (int32_t k = 0; k < m; ++k) {
    int32_t p = k;
    double big = fabs(a[(int64_t)k * m + k]);
    for (int32_t i = k + 1; i < m; ++i)
      if (fabs(a[(int64_t)i * m + k]) > big) big = fabs(a[(int64_t)i * m + k]), p = i;
    piv[k] = p;
    if (!(big > 0.0) || !isfinite(big)) return 1;
    if (p != k)
      for (int32_t j = 0; j < m; ++j) {
        const double t = a[(int64_t)k * m + j];
        a[(int64_t)k * m + j] = a[(int64_t)p * m + j];
        a[(int64_t)p * m + j] = t;
      }
    const double inv = 1.0 / a[(int64_t)k * m + k];
    for (int32_t i = k + 1; i < m; ++i) {
      double* ai = a + (int64_t)i * m;
      const double f = ai[k] * inv;
      ai[k] = f;
      if (f == 0.0) continue;
      const double* ak = a + (int64_t)k * m;
      for (int32_t j = k + 1; j < m; ++j) ai[j] -= f * ak[j];
    }
  }
  return 0;
}

static void lu_solve(const double* a, const int32_t* piv, int32_t m, double* x)
{
  for (int32_t k = 0; k < m; ++k)
    if (piv[k] != k) {
      const double t = x[k];
      x[k] = x[piv[k]];
      x[piv[k]] = t;
    }
  for (int32_t i = 1; i < m; ++i) {
    double s = x[i];
    for (int32_t j = 0; j < i; ++j) s -= a[(int64_t)i * m + j] * x[j];
    x[i] = s;
  }
  for (int32_t i = m - 1; i >= 0; --i) {
    double s = x[i];
    for (int32_t j = i + 1; j < m; ++j) s -= a[(int64_t)i * m + j] * x[j];
    x[i] = s / a[(int64_t)i * m + i];
  }
}

/* x^T G y */
static double gram(const double* G, int32_t m, const double* x, const double* y)
{
  double s = 0.0;
  for (int32_t i = 0; i < m; ++i) {
    double t = 0.0;
    for (int32_t j = 0; j < m; ++j) t += G[(int64_t)i * m + j] * y[j];
    s += x[i] * t;
  }
  return s;
}

/* U = U_ref + V q on the entries `rows` of U. */
static void write_rows(const cf_reduced* R, double* u, const int32_t* rows, int32_t count)
{
  const int32_t m = R->m;
  for (int32_t k = 0; k < count; ++k) {
    const int32_t i = rows[k];
    const double* v = R->V + (int64_t)i * m;
    double s = 0.0;
    for (int32_t j = 0; j < m; ++j) s += v[j] * R->q[j];
    u[i] = R->ref[i] + s;
  }
}

/* values = a U_ref + V c on the entries `rows` (a = 1 a state, 0 a rate), from VT: the sums
 * of each entry in write_rows' order (j = 0..m-1 from 0.0), so the same doubles, but with
 * the entries independent in the inner loop (no chain of m dependent additions per entry). */
static void set_values(const cf_reduced* R, double* values, const double* c, double affine)
{
  const int32_t nr = R->n_rows, m = R->m;
  double* t = R->t;
  memset(t, 0, sizeof(double) * (size_t)nr);
  for (int32_t j = 0; j < m; ++j) {
    const double cj = c[j];
    const double* vt = R->VT + (int64_t)j * nr;
    for (int32_t k = 0; k < nr; ++k) t[k] += vt[k] * cj;
  }
  for (int32_t k = 0; k < nr; ++k) {
    const int32_t i = R->rows[k];
    values[i] = affine * R->ref[i] + t[k];
  }
}

/* U's entries the sampled entities read: U_ref + V q there. */
static void set_rows(cf_reduced* R, double* u) { set_values(R, u, R->q, 1.0); }

static int reduced_residual(cf_reduced* R, double* fnorm)
{
  const double t0 = now();
  cf_reduced_residual(R->F, R->DV, R->m, R->r, NULL);
  R->st->time_residual += now() - t0;
  R->st->residuals += 1;
  double s = 0.0;
  for (int32_t j = 0; j < R->m; ++j) s += R->r[j] * R->r[j];
  *fnorm = sqrt(s);
  return 0;
}

static int reduced_test(cf_reduced* R, int it, const double* norms, int* reason)
{
  *reason = cf_test(R->s, R->st, it, norms);
  const cf_observe observe = R->solver->on_iteration;
  return observe ? observe(R->observer, it, norms, *reason) : 0;
}

/* q0 of the guess in U. Every state the integrator forms from reduced states (stage values,
 * rates, predictors: linear combinations) lies in U_ref + span V, so q0 is read off the rows
 * S alone, q0 = P (U - U_ref)_S, P = V_S^+ (O(|S| m)), and checked there: if V_S q0 misses
 * (U - U_ref)_S by more than 1e-9 of its largest entry (a state off the basis), and at the
 * first solve (project_all), it is the W-projection over every row, q0 = (W V)^T (U - U_ref)
 * (O(n m)). */
static void project(cf_reduced* R, const double* u)
{
  const int32_t m = R->m;
  if (!R->project_all && R->n_fit) {
    for (int32_t j = 0; j < m; ++j) {
      const double* p = R->P + (int64_t)j * R->n_fit;
      double t = 0.0;
      for (int32_t k = 0; k < R->n_fit; ++k) t += p[k] * (u[R->fit[k]] - R->ref[R->fit[k]]);
      R->q[j] = t;
    }
    double miss = 0.0, size = 0.0;
    for (int32_t k = 0; k < R->n_fit; ++k) {
      const int32_t i = R->fit[k];
      const double* v = R->V + (int64_t)i * m;
      double t = 0.0;
      for (int32_t j = 0; j < m; ++j) t += v[j] * R->q[j];
      const double d = u[i] - R->ref[i];
      if (fabs(t - d) > miss) miss = fabs(t - d);
      if (fabs(d) > size) size = fabs(d);
    }
    if (miss <= 1e-9 * size) return;
  }
  memset(R->q, 0, sizeof(double) * (size_t)m);
  for (int32_t i = 0; i < R->n; ++i) {
    const double d = u[i] - R->ref[i];
    if (d == 0.0) continue;
    const double* w = R->WV + (int64_t)i * m;
    for (int32_t j = 0; j < m; ++j) R->q[j] += w[j] * d;
  }
  R->project_all = 0;
  R->full_projections += 1;
}

/* A cf_run (ctx: a cf_reduced): the reduced Newton iterations from the guess in U; U then
 * holds U_ref + V q of the last iterate. */
int cf_reduced_run(void* ctx, int* iterations, int* reason)
{
  cf_reduced* R = (cf_reduced*)ctx;
  const cf_settings* s = R->s;
  cf_newton_state* st = R->st;
  const int32_t m = R->m;
  double* u = (double*)R->F->u_values;
  int ierr, it = 0;
  double fnorm;
  *iterations = 0;
  if (R->coordinates)
    for (int32_t f = 0; f < R->n_lifts; ++f) /* the integrator's Functions on the rows */
      set_values(R, R->lift_values[f], R->lift_coords[f], R->lift_affine[f]);
  else
    project(R, u);
  set_rows(R, u);
  reduced_residual(R, &fnorm);
  if (!isfinite(fnorm)) {
    *reason = SNES_DIVERGED_FNORM_NAN;
    goto done;
  }
  const double first[3] = {0.0, 0.0, fnorm};
  if ((ierr = reduced_test(R, 0, first, reason))) return ierr;
  while (*reason == SNES_CONVERGED_ITERATING && it < s->max_iterations) {
    if (st->need_jacobian || s->full) {
      const double t0 = now();
      cf_reduced_jacobian(R->J, R->DV, R->V, m, R->Jr, R->work);
      memcpy(R->lu, R->Jr, sizeof(double) * (size_t)m * (size_t)m);
      R->factored = !lu_factor(R->lu, R->piv, m);
      R->jacobians += 1;
      R->time_jacobian += now() - t0;
      st->need_jacobian = 0;
      st->since = 0;
    }
    if (!R->factored) {
      *reason = SNES_DIVERGED_LINEAR_SOLVE;
      break;
    }
    memcpy(R->dq, R->r, sizeof(double) * (size_t)m);
    lu_solve(R->lu, R->piv, m, R->dq);
    for (int32_t j = 0; j < m; ++j) R->q[j] -= R->dq[j];
    set_rows(R, u);
    reduced_residual(R, &fnorm);
    if (!isfinite(fnorm)) {
      *reason = SNES_DIVERGED_FNORM_NAN;
      break;
    }
    double x2 = R->c, y2 = gram(R->G, m, R->dq, R->dq);
    for (int32_t j = 0; j < m; ++j) x2 += 2.0 * R->g[j] * R->q[j];
    x2 += gram(R->G, m, R->q, R->q);
    st->norms[0] = sqrt(x2 > 0.0 ? x2 : 0.0);
    st->norms[1] = sqrt(y2 > 0.0 ? y2 : 0.0);
    st->norms[2] = fnorm;
    it += 1;
    *iterations = it;
    if ((ierr = reduced_test(R, it, st->norms, reason))) return ierr;
  }
  if (*reason == SNES_CONVERGED_ITERATING) *reason = SNES_DIVERGED_MAX_IT;
done:
  /* the whole state, for the integrator: U = U_ref + V q (the sampled rows hold it already,
   * set by the same arithmetic); in reduced coordinates the integrator's state is q */
  if (!R->coordinates) write_rows(R, u, R->rest, R->n_rest);
  return 0;
}

/* A cf_guess (ctx: a cf_reduced in reduced coordinates): q kept in q0 (restore = 0) or put
 * back from it (1), O(m) where cf_solve's VecCopy of U is O(n). */
int cf_reduced_guess(void* ctx, int restore)
{
  cf_reduced* R = (cf_reduced*)ctx;
  if (restore)
    memcpy(R->q, R->q0, sizeof(double) * (size_t)R->m);
  else
    memcpy(R->q0, R->q, sizeof(double) * (size_t)R->m);
  return 0;
}

/* U = U_ref + a V q on the entries `rows` of `u` (a = 1 a state, 0 a rate): the lift of
 * reduced coordinates q onto a full array (all rows, or a probe's), (n, m) V row-major. */
void cf_lift(const double* V, const double* ref, int32_t m, const double* q, double affine,
             const int32_t* rows, int32_t count, double* u)
{
  for (int32_t k = 0; k < count; ++k) {
    const int32_t i = rows ? rows[k] : k;
    const double* v = V + (int64_t)i * m;
    double s = 0.0;
    for (int32_t j = 0; j < m; ++j) s += v[j] * q[j];
    u[i] = affine * ref[i] + s;
  }
}
