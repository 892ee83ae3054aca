/*
 * touchdown_rollout(x0, p, dt) -> (X, Y): ROLLOUT_STEPS calls of touchdown_step.
 *
 * symcushion.compiled.codegen appends this file to the generated touchdown source, after
 * CasADi's touchdown_step, with ROLLOUT_NX, ROLLOUT_NY, ROLLOUT_NP, ROLLOUT_NQ
 * and ROLLOUT_STEPS defined before it. It is the Function CasADi would generate
 * from touchdown_step.mapaccum(N) (same name, inputs, outputs, calling convention and
 * API, so casadi.external loads it) written as a loop: step k reads column k - 1
 * of X (x0 for the first) and writes column k of X and of Y in place, where the
 * mapaccum passes every state and output through work arrays and copies them out
 * level by level. The steps and their arguments are those of the mapaccum, so
 * the results are the same bits.
 *
 * The step is called split at its parameters (symcushion.compiled.codegen.hoisted_step):
 * touchdown_step_parametric(p) -> q once, the values of the step that depend on
 * p alone (ROLLOUT_NQ of them), then touchdown_step_core(x, p, dt, q) in the
 * loop, the rest of the step. The two execute the step's own operations, so
 * the results are those of touchdown_step, bit for bit. Where ROLLOUT_STATES is
 * 1, a call with a null Y runs touchdown_step_states instead of
 * touchdown_step_core: the core cut at x_next, without the per-step outputs
 * (the same operations for x_next, so X is the same bits; generated only where
 * the outputs are a tenth of the core or more, symcushion.codegen_hoist).
 *
 * Work: the largest of the three Functions' arg, res, iw and w after this
 * function's own (3 inputs, 2 outputs), two states for a call that does not
 * want X, and q.
 */

static const casadi_int rollout_sp_x0[3] = {ROLLOUT_NX, 1, 1};
static const casadi_int rollout_sp_p[3] = {ROLLOUT_NP, 1, 1};
static const casadi_int rollout_sp_dt[3] = {1, 1, 1};
static const casadi_int rollout_sp_X[3] = {ROLLOUT_NX, ROLLOUT_STEPS, 1};
static const casadi_int rollout_sp_Y[3] = {ROLLOUT_NY, ROLLOUT_STEPS, 1};
static const casadi_real rollout_zeros[ROLLOUT_NX] = {0.};

CASADI_SYMBOL_EXPORT int touchdown_rollout(const casadi_real** arg, casadi_real** res,
                                           casadi_int* iw, casadi_real* w, int mem) {
  const casadi_real **arg1 = arg + 3;
  casadi_real **res1 = res + 2, *X = res[0], *Y = res[1];
  casadi_real *spare[2], *q;
  const casadi_real *x;
  casadi_int k;
  (void)mem;
  spare[0] = w;
  spare[1] = w + ROLLOUT_NX;
  q = w + 2 * ROLLOUT_NX;
  w += 2 * ROLLOUT_NX + ROLLOUT_NQ;
  x = arg[0] ? arg[0] : rollout_zeros;
  /* a null p or dt is read as zeros by the step's Functions themselves */
  arg1[0] = arg[1];
  res1[0] = q;
  if (touchdown_step_parametric(arg1, res1, iw, w, 0)) return 1;
  arg1[1] = arg[1];
  arg1[2] = arg[2];
  arg1[3] = q;
  for (k = 0; k < ROLLOUT_STEPS; ++k) {
    casadi_real *x_next = X ? X + k * ROLLOUT_NX : spare[k % 2];
    arg1[0] = x;
    res1[0] = x_next;
    res1[1] = Y ? Y + k * ROLLOUT_NY : 0;
#if ROLLOUT_STATES
    if (!Y) {
      if (touchdown_step_states(arg1, res1, iw, w, 0)) return 1;
      x = x_next;
      continue;
    }
#endif
    if (touchdown_step_core(arg1, res1, iw, w, 0)) return 1;
    x = x_next;
  }
  return 0;
}

CASADI_SYMBOL_EXPORT int touchdown_rollout_checkout(void) { return 0; }
CASADI_SYMBOL_EXPORT void touchdown_rollout_release(int mem) { (void)mem; }
CASADI_SYMBOL_EXPORT void touchdown_rollout_incref(void) {
  touchdown_step_parametric_incref();
  touchdown_step_core_incref();
#if ROLLOUT_STATES
  touchdown_step_states_incref();
#endif
}
CASADI_SYMBOL_EXPORT void touchdown_rollout_decref(void) {
  touchdown_step_parametric_decref();
  touchdown_step_core_decref();
#if ROLLOUT_STATES
  touchdown_step_states_decref();
#endif
}
CASADI_SYMBOL_EXPORT casadi_int touchdown_rollout_n_in(void) { return 3; }
CASADI_SYMBOL_EXPORT casadi_int touchdown_rollout_n_out(void) { return 2; }

CASADI_SYMBOL_EXPORT casadi_real touchdown_rollout_default_in(casadi_int i) {
  (void)i;
  return 0;
}

CASADI_SYMBOL_EXPORT const char* touchdown_rollout_name_in(casadi_int i) {
  switch (i) {
    case 0: return "x0";
    case 1: return "p";
    case 2: return "dt";
    default: return 0;
  }
}

CASADI_SYMBOL_EXPORT const char* touchdown_rollout_name_out(casadi_int i) {
  switch (i) {
    case 0: return "X";
    case 1: return "Y";
    default: return 0;
  }
}

CASADI_SYMBOL_EXPORT const casadi_int* touchdown_rollout_sparsity_in(casadi_int i) {
  switch (i) {
    case 0: return rollout_sp_x0;
    case 1: return rollout_sp_p;
    case 2: return rollout_sp_dt;
    default: return 0;
  }
}

CASADI_SYMBOL_EXPORT const casadi_int* touchdown_rollout_sparsity_out(casadi_int i) {
  switch (i) {
    case 0: return rollout_sp_X;
    case 1: return rollout_sp_Y;
    default: return 0;
  }
}

CASADI_SYMBOL_EXPORT int touchdown_rollout_work(casadi_int *sz_arg, casadi_int* sz_res,
                                                casadi_int *sz_iw, casadi_int *sz_w) {
  casadi_int most[4] = {0, 0, 0, 0}, one[4], f, i;
  for (f = 0; f < 3; ++f) {
    if (f == 0) touchdown_step_core_work(one, one + 1, one + 2, one + 3);
#if ROLLOUT_STATES
    if (f == 1) touchdown_step_states_work(one, one + 1, one + 2, one + 3);
#endif
    if (f == 2) touchdown_step_parametric_work(one, one + 1, one + 2, one + 3);
    for (i = 0; i < 4; ++i) if (one[i] > most[i]) most[i] = one[i];
  }
  if (sz_arg) *sz_arg = 3 + most[0];
  if (sz_res) *sz_res = 2 + most[1];
  if (sz_iw) *sz_iw = most[2];
  if (sz_w) *sz_w = 2 * ROLLOUT_NX + ROLLOUT_NQ + most[3];
  return 0;
}

CASADI_SYMBOL_EXPORT int touchdown_rollout_work_bytes(casadi_int *sz_arg, casadi_int* sz_res,
                                                      casadi_int *sz_iw, casadi_int *sz_w) {
  touchdown_rollout_work(sz_arg, sz_res, sz_iw, sz_w);
  if (sz_arg) *sz_arg *= sizeof(const casadi_real*);
  if (sz_res) *sz_res *= sizeof(casadi_real*);
  if (sz_iw) *sz_iw *= sizeof(casadi_int);
  if (sz_w) *sz_w *= sizeof(casadi_real);
  return 0;
}
