/* neck_sim plant callback (MuJoCo mjcb_control), compiled at first use by neck_sim/native/__init__.py.

   Physics: eq (54) cable tensions and eq (37) motor friction plus the motor-side effects of
   neck_sim.effects (viscous, Stribeck, pulley friction), the same laws as the Python reference
   (neck_sim.analytic.dynamics.cable_tension / motor_friction and Effect.motor_force).

   Per-step state written into the model.  MuJoCo has no per-step actuator input besides ctrl,
   which carries the commanded forces, so at every physics step neck_control overwrites, for this
   plant's own actuators only, actuator_biasprm[:, 0:3] of the *mjModel* in the affine form
   bias = b0 + b1 * length + b2 * velocity:
     tension{j}: b0 = -t + (dt/dxd) xd, b1 = 0, b2 = -(dt/dxd)      (t of eq 54, xd the tendon speed)
     drive{j}:   b0 = -f + (df/dw) w,   b1 = 0, b2 = -(df/dw) ratio  (f the friction at motor speed w)
   (the tension actuators are left alone with rigid cables), so the implicitfast integrator treats
   cable damping and friction implicitly.  Hence a plant's mjModel must not be shared with another
   simulation, and its biasprm describes only the last step.  Everything else the callback writes
   goes into the neck_plant struct (the outputs below).

   Stepping: neck_step_batch runs one control period of K plants (mj_step2, mj_step x (nsub-1),
   mj_step1, as neck_sim.plant.PlantBatch describes), linked against the MuJoCo library of the
   Python package, so the sub-steps, camera captures and outputs cost no Python.

   Dispatch: callbacks are process-global; neck_control looks the model up among registered plants
   (neck_register) and returns at once for any other model.

   The struct neck_plant below is the only declaration of the parameter/output layout: the Python
   ctypes mirror is generated from its text (neck_sim.native.PlantStruct), so keep each member a
   plain `int` or `double`, scalar or [NECK_MAXC]. */
#include <math.h>
#include <mujoco/mujoco.h>

#define NECK_MAXC 32          /* cables per plant (the ctypes mirror reads this value too) */
#define NECK_MAXPLANTS 256    /* live plants per process */

typedef struct {
  /* sizes and model indices (njoint of them for the per-joint rows qA..site2) */
  int ncable, rigid, njoint;
  int tendon[NECK_MAXC], dof[NECK_MAXC], qmotor[NECK_MAXC], act_drive[NECK_MAXC], act_tension[NECK_MAXC];
  int qA[NECK_MAXC], qD[NECK_MAXC], vA[NECK_MAXC], vD[NECK_MAXC], site1[NECK_MAXC], site2[NECK_MAXC];
  /* rigid cables: equality constraint id of each cable (its tension is that constraint's force) */
  int eq_rigid[NECK_MAXC];
  /* parameters, SI units: ratio R/r_d (rad/m), t_cap (N), rest length and pretension offset (m);
     encoder resolution (rad) and its inverse */
  double ratio, t_cap, res, inv_res;
  double rest[NECK_MAXC], x_pre[NECK_MAXC];
  /* eq (54): k (N/m), lam (1/m), c_a (N s/m) */
  double k[NECK_MAXC], lam[NECK_MAXC], c_a[NECK_MAXC];
  /* eq (37) f_s (N), c_s (s/rad); viscous c_v (N s/rad) */
  double f_s[NECK_MAXC], c_s[NECK_MAXC], c_v[NECK_MAXC];
  /* Stribeck: df (N), speed (rad/s), smoothing (rad/s) */
  double st_df[NECK_MAXC], st_speed[NECK_MAXC], st_smooth[NECK_MAXC];
  /* pulley friction: mu (1), c (s/rad) */
  double pf_mu[NECK_MAXC], pf_c[NECK_MAXC];
  /* outputs of the last call: N, m, m/s, rad, rad/s, m; calls counts invocations */
  double tension[NECK_MAXC], elongation[NECK_MAXC], elongation_rate[NECK_MAXC];
  double alpha[NECK_MAXC], alpha_dot[NECK_MAXC], theta[NECK_MAXC], theta_dot[NECK_MAXC];
  double loop_gap, calls;
} neck_plant;

static const void* keys[NECK_MAXPLANTS];
static neck_plant* vals[NECK_MAXPLANTS];
static int nslots = 0;

int neck_register(const void* m, neck_plant* p) {
  int free_slot = -1;
  for (int i = 0; i < nslots; i++) {
    if (keys[i] == m) { vals[i] = p; return i; }
    if (!keys[i] && free_slot < 0) free_slot = i;
  }
  if (free_slot < 0) {
    if (nslots >= NECK_MAXPLANTS) return -1;
    free_slot = nslots++;
  }
  vals[free_slot] = p;
  keys[free_slot] = m;
  return free_slot;
}

int neck_unregister(const void* m) {
  for (int i = 0; i < nslots; i++) {
    if (keys[i] == m) { keys[i] = 0; vals[i] = 0; return 1; }
  }
  return 0;
}

int neck_registered(void) {
  int n = 0;
  for (int i = 0; i < nslots; i++) n += keys[i] != 0;
  return n;
}

/* eq (54) solved for t: t = (k x + c_a x_dot) / (1 - lam x), 0 when slack, linear above t_cap.
   out[0] = t, out[1] = d t / d x_dot. */
void neck_tension(const neck_plant* p, int j, double x, double xd, double* out) {
  out[0] = 0; out[1] = 0;
  if (!(x > 0)) return;
  double k = p->k[j], lam = p->lam[j], ca = p->c_a[j];
  double xs = p->t_cap / (k + lam * p->t_cap);
  double xe = x < xs ? x : xs;
  double denom = 1.0 - lam * xe;
  double t = k * xe / denom + ca * xd / denom;
  if (x > xs) t += (x - xs) * k / ((1.0 - lam * xs) * (1.0 - lam * xs));
  if (t > 0) { out[0] = t; out[1] = ca / denom; }
}

/* friction along the cable resisting the motor speed w (rad/s): eq (37) + viscous + Stribeck +
   pulley (tension t).  out[0] = force (N), out[1] = d force / d w. */
void neck_friction(const neck_plant* p, int j, double w, double t, double* out) {
  const double c2pi = 0.63661977236758134308;  /* 2/pi */
  double cs = p->c_s[j];
  double f = c2pi * p->f_s[j] * atan(cs * w);
  double df = c2pi * p->f_s[j] * cs / (1.0 + cs * cs * w * w);
  f += p->c_v[j] * w;
  df += p->c_v[j];
  if (p->st_df[j] != 0) {
    double u = w / p->st_speed[j], e = exp(-u * u), th = tanh(w / p->st_smooth[j]);
    f += p->st_df[j] * e * th;
    df += p->st_df[j] * e * ((1.0 - th * th) / p->st_smooth[j] - 2.0 * u / p->st_speed[j] * th);
  }
  if (p->pf_mu[j] != 0) {
    double c = p->pf_c[j];
    f += p->pf_mu[j] * t * c2pi * atan(c * w);
    df += p->pf_mu[j] * t * c2pi * c / (1.0 + c * c * w * w);
  }
  out[0] = f; out[1] = df;
}

/* joint angles and the largest loop-closure gap, for the plant's truth */
void neck_sense(neck_plant* p, const mjData* d) {
  double gap2 = 0;
  for (int i = 0; i < p->njoint; i++) {
    p->alpha[i] = d->qpos[p->qA[i]] + d->qpos[p->qD[i]];
    p->alpha_dot[i] = d->qvel[p->vA[i]] + d->qvel[p->vD[i]];
    const mjtNum* a = d->site_xpos + 3 * p->site1[i];
    const mjtNum* b = d->site_xpos + 3 * p->site2[i];
    double g = (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]);
    if (g > gap2) gap2 = g;
  }
  p->loop_gap = sqrt(gap2);
}

void neck_control(const mjModel* m, mjData* d) {
  neck_plant* p = 0;
  for (int i = 0; i < nslots; i++) {
    if (keys[i] == (const void*)m) { p = vals[i]; break; }
  }
  if (!p) return;
  mjtNum* bias = ((mjModel*)m)->actuator_biasprm;   /* per-step parameters of this model's own actuators */
  for (int j = 0; j < p->ncable; j++) {
    int tj = p->tendon[j];
    double x = d->ten_length[tj] - p->rest[j] + p->x_pre[j];
    double xd = d->ten_velocity[tj];
    double tv[2] = {0, 0}, fv[2];
    if (!p->rigid) {
      neck_tension(p, j, x, xd, tv);
      mjtNum* b = bias + mjNBIAS * p->act_tension[j];
      b[0] = -tv[0] + tv[1] * xd; b[1] = 0; b[2] = -tv[1];
    }
    p->tension[j] = tv[0];
    p->elongation[j] = x;
    p->elongation_rate[j] = xd;
    double sd = d->qvel[p->dof[j]];
    neck_friction(p, j, p->ratio * sd, tv[0], fv);
    mjtNum* b = bias + mjNBIAS * p->act_drive[j];
    b[0] = -fv[0] + fv[1] * p->ratio * sd; b[1] = 0; b[2] = -fv[1] * p->ratio;
    p->theta[j] = p->ratio * d->qpos[p->qmotor[j]];
    p->theta_dot[j] = p->ratio * sd;
  }
  neck_sense(p, d);
  p->calls += 1;
}

/* Tensions of rigid cables (N): minus the force of each cable's equality constraint in the last
   sub-step (0 if the constraint is not active); read before mj_step1 rebuilds the constraints. */
static void rigid_tensions(const neck_plant* p, const mjData* d, double* out) {
  for (int j = 0; j < p->ncable; j++) {
    out[j] = 0;
    for (int r = 0; r < d->nefc; r++) {
      if (d->efc_type[r] == mjCNSTR_EQUALITY && d->efc_id[r] == p->eq_rigid[j]) { out[j] = -d->efc_force[r]; break; }
    }
  }
}

/* One control period of K plants (the registered callback must be installed as mjcb_control).
   Plant i (skipped when active[i] == 0) runs mj_step2, mj_step x (nsub - 1), mj_step1 with
   ctrl[0:ncable] set before each sub-step s to ctrl + (i nsub + s) ncable (ctrl_per_substep) or
   ctrl + i ncable; where capture[i nsub + s] != 0 (capture may be NULL) the joint angles after
   sub-step s go to frame_alpha + (i nsub + s) njoint.  Then substep[i] grows by nsub, out + i nout
   receives theta (ncable), alpha, alpha_dot (njoint), tension, elongation (ncable), loop_gap,
   encoders + i ncable the encoder reading of theta (nearest count of res, as Plant.encoders), and
   fatal[i] is 1 if MuJoCo reported a singular inertia or a bad qpos / qvel / qacc since the last
   reset.
   Returns how many active plants have fatal set, or -1 (nothing stepped) if a plant's sizes
   differ from ncable, njoint. */
int neck_step_batch(int K, neck_plant* const* plants, const mjModel* const* models, mjData* const* datas,
                    const unsigned char* active, int nsub, int ncable, int njoint,
                    const double* ctrl, int ctrl_per_substep, const int* capture, double* frame_alpha,
                    long long* substep, double* out, double* encoders, int* fatal) {
  int nout = 3 * ncable + 2 * njoint + 1, nfatal = 0;
  for (int i = 0; i < K; i++) {
    if (plants[i]->ncable != ncable || plants[i]->njoint != njoint) return -1;
  }
  for (int i = 0; i < K; i++) {
    if (!active[i]) continue;
    neck_plant* p = plants[i];
    const mjModel* m = models[i];
    mjData* d = datas[i];
    for (int s = 0; s < nsub; s++) {
      const double* c = ctrl + (ctrl_per_substep ? (i * nsub + s) : i) * ncable;
      for (int j = 0; j < ncable; j++) d->ctrl[p->act_drive[j]] = c[j];
      if (s == 0) mj_step2(m, d); else mj_step(m, d);
      if (capture && capture[i * nsub + s]) {
        double* a = frame_alpha + (i * nsub + s) * njoint;
        for (int q = 0; q < njoint; q++) a[q] = d->qpos[p->qA[q]] + d->qpos[p->qD[q]];
      }
    }
    double rigid[NECK_MAXC];
    if (p->rigid) rigid_tensions(p, d, rigid);
    mj_step1(m, d);
    if (p->rigid) for (int j = 0; j < ncable; j++) p->tension[j] = rigid[j];
    double* o = out + i * nout;
    substep[i] += nsub;
    for (int j = 0; j < ncable; j++) {
      o[j] = p->theta[j];
      encoders[i * ncable + j] = rint(p->theta[j] * p->inv_res) * p->res;
      o[ncable + 2 * njoint + j] = p->tension[j];
      o[2 * ncable + 2 * njoint + j] = p->elongation[j];
    }
    for (int q = 0; q < njoint; q++) { o[ncable + q] = p->alpha[q]; o[ncable + njoint + q] = p->alpha_dot[q]; }
    o[nout - 1] = p->loop_gap;
    fatal[i] = d->warning[mjWARN_INERTIA].number > 0 || d->warning[mjWARN_BADQPOS].number > 0 ||
               d->warning[mjWARN_BADQVEL].number > 0 || d->warning[mjWARN_BADQACC].number > 0;
    nfatal += fatal[i];
  }
  return nfatal;
}
