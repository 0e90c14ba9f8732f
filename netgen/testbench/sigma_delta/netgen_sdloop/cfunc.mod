/* netgen sigma-delta loop (ifspec.ifs): the discrete-time blocks of the `netgen sigma-delta`
   testbench (netgen/testbench/sigma_delta, templates/sigma_delta/tb.cir.j2) as one compiled instance.
   Per channel c, once per period n (period index n + start, instants (n + phase) ts):
     at t_sample:  prev[c] = cur[c];  cur[c] = ca[c](t)       (the charge amplifier, interpolated
                   linearly between the accepted time points around the instant: exact timing
                   without a breakpoint)
     at t_latch:   b[c] = 1 if lead prev[c] - cur[c] + dither_amp[c] sin(dither_step[c] n) > 0 else 0
                   (lead: leads[c] when the vector leads is given, else the scalar lead)
                   or, for a channel with flt_n[c] = K > 0 filter states u (the higher-order loops of
                   netgen/testbench/sigma_delta/filters.py; sd_filter below):
                   y = flt_c . u + flt_d[c] cur[c] + dither,  b[c] = [y > 0],  v = 2 b[c] - 1,
                   u <- flt_a u + flt_bx cur[c] + flt_bv v   (u: on the optional port u; u0 at t = 0)
                   with cur[c] - flt_x0[c] for cur[c] in both (the readout's rest value trimmed)
   and per electrode e, at every time point,
     drv[e] = sum_j ph_sense[j] ph[j] + s_e(b) sum_j ph_fb[j] ph[j],
     s_e(b) = prod_c (b[c] if sel[e,c] = +1, 1 - b[c] if -1, 1 if 0), and 0 if every sel[e,c] = 0
              (an electrode in no feedback pattern only senses).
   ph[j] are inputs (ph_pulse is then ignored: give [0]), or (ph NULL) the instance's own PULSE
   waveforms ph_pulse[7 j ..] of TIME,
   evaluated as ngspice's PULSE source evaluates them: the drives then have no inputs to stamp
   (an XSPICE instance stamps every output x input pair; the netlist keeps the PULSE sources for
   their breakpoints).
   With fb_level != 0 the feedback drive is also a step: fb_level on (fb_on, fb_off] of every period
   (phases), with the instance's own breakpoints at both instants. ngspice takes the first step after
   a breakpoint by backward Euler, which integrates a force that is constant over the step exactly, so
   the proof mass gets the same impulse whatever the time steps are; a ramped feedback phase's V^2
   force is integrated with an error that depends on the step partition inside the ramps, which
   varies from period to period with the other nodes' truncation errors (measured on the z
   accelerometer: 8.6e-5 of the impulse rms, white: a flat in-band floor near -138 dB/Hz that hid a
   fourth-order loop's shaping; bench/sigma_delta_impulse.py).
   The state (time, ca, cur, prev, b of the last accepted time point) is XSPICE rotating analog
   state, so a rejected time point is recomputed from the accepted one. cur0, prev0 and b0 set it
   at t = 0: a segment restarted at t = 0 continues the run. */

#include <math.h>
#include <stdio.h>
#include <string.h>

#define SD_MAX_K 8           /* filter states per channel (order 5 needs 3) */

enum { ST_T, ST_HEAD };      /* state layout: t, then ca[C], cur[C], prev[C], b[C], u[sum flt_n] */

/* ngspice's PULSE(v1 v2 td tr tf pw per) at time t (src/spicelib/devices/vsrc/vsrcload.c) */
static double sd_pulse(const double *p, double t)
{
    double v1 = p[0], v2 = p[1], td = p[2], tr = p[3], tf = p[4], pw = p[5], per = p[6];
    t -= td;
    if (per > 0.0 && t > per) t -= per * floor(t / per);
    if (t <= 0.0 || t >= tr + pw + tf) return v1;
    if (t >= tr && t <= tr + pw) return v2;
    if (t > 0.0 && t < tr) return v1 + (v2 - v1) * t / tr;
    return v2 + (v1 - v2) * (t - tr - pw) / tf;
}

/* a time point within SD_GUARD periods after a step instant still sees the old level (ngspice may
   land a point a few ULPs past a breakpoint; the step is taken by the backward-Euler step after it) */
#define SD_GUARD 1e-6

/* the feedback step's level at time t: fb_level on (fb_on, fb_off] of the period, else 0 */
static double sd_step(ARGS, double t)
{
    double ts = PARAM(ts), p;
    if (PARAM_NULL(fb_level) || PARAM(fb_level) == 0.0) return 0.0;
    p = t / ts - floor(t / ts);
    return (p > PARAM(fb_on) + SD_GUARD && p <= PARAM(fb_off) + SD_GUARD) ? PARAM(fb_level) : 0.0;
}

/* a second breakpoint SD_SETTLE periods after each step instant: its backward-Euler step ends the
   trapezoidal rule's ringing of the electrode currents after the voltage step (the current of the
   step's own backward-Euler step, C dV / h, would otherwise alternate in sign from step to step and
   reach the charge amplifiers when their input opens) */
#define SD_SETTLE 1e-3

/* the feedback step's next instant (or its settling point) after TIME as a permanent breakpoint
   (ngspice merges repeats) */
static void sd_step_breakpoint(ARGS)
{
    double ts = PARAM(ts), k, best = -1.0;
    int j;
    if (PARAM_NULL(fb_level) || PARAM(fb_level) == 0.0 || ANALYSIS != MIF_TRAN) return;
    k = floor(TIME / ts);
    for (j = 0; j < 8; j++) {
        double te = (k + (double) (j / 4) + ((j / 2) % 2 ? PARAM(fb_off) : PARAM(fb_on)) + (j % 2 ? SD_SETTLE : 0.0)) * ts;
        if (te > TIME + SD_GUARD * ts && (best < 0.0 || te < best)) best = te;
    }
    if (best > 0.0) cm_analog_set_perm_bkpt(best);
}

/* ramp_steps = N > 0: ngspice crosses every edge of the drives (an interval between the PULSE
   corners of ph_pulse on which the sense or the feedback drive changes) in N equal steps, through a
   temporary breakpoint at each grid point. Without it the steps inside an edge are the ones its
   breakpoint restart doubles up from 1/10 of the step before (on a 20 ns edge: 0.08, 0.16, .. 9.8 ns),
   and the trapezoidal rule's error on the edge's V^2 force (h^3/12 of its second derivative per step)
   reaches 2e-3 of the feedback impulse and changes with the partition from period to period; its
   truncation-error control does not see it (its tolerance is relative to the velocity node's whole
   charge). On the grid the error is h^2 / (6 t_edge) of the level's force per edge up and down, the
   same every period. ngspice takes the step after each temporary breakpoint by backward Euler, whose
   first-order errors cancel between an edge up and an edge down of the same level
   (bench/fmu_convergence.py measures it). */
#define SD_MAX_EDGES 32

/* the drives' edges of one period: [lo[i], hi[i]) in seconds within [0, ts); returns their number */
static int sd_edges(ARGS, int J, double *lo, double *hi)
{
    double ts = PARAM(ts), c[4 * 8 + 2], wsum = 0.0;
    int n = 0, j, q, m = 0;
    for (j = 0; j < J && j < 8; j++) {
        double td = PARAM(ph_pulse[7 * j + 2]), tr = PARAM(ph_pulse[7 * j + 3]);
        double tf = PARAM(ph_pulse[7 * j + 4]), pw = PARAM(ph_pulse[7 * j + 5]);
        double at[4];
        at[0] = td; at[1] = td + tr; at[2] = td + tr + pw; at[3] = td + tr + pw + tf;
        for (q = 0; q < 4; q++) c[n++] = at[q] - ts * floor(at[q] / ts);
        wsum += fabs(PARAM(ph_sense[j])) + fabs(PARAM(ph_fb[j]));
    }
    c[n++] = 0.0;
    c[n++] = ts;
    for (j = 1; j < n; j++)            /* insertion sort */
        for (q = j; q > 0 && c[q - 1] > c[q]; q--) { double x = c[q]; c[q] = c[q - 1]; c[q - 1] = x; }
    for (q = 0; q + 1 < n && m < SD_MAX_EDGES; q++) {
        double a = c[q], b = c[q + 1], ds = 0.0, df = 0.0;
        if (b - a < 1e-9 * ts) continue;
        for (j = 0; j < J && j < 8; j++) {
            double p[7], v;
            int k;
            for (k = 0; k < 7; k++) p[k] = PARAM(ph_pulse[7 * j + k]);
            v = sd_pulse(p, a + 0.75 * (b - a)) - sd_pulse(p, a + 0.25 * (b - a));
            ds += PARAM(ph_sense[j]) * v;
            df += PARAM(ph_fb[j]) * v;
        }
        if (fabs(ds) > 1e-12 * wsum || fabs(df) > 1e-12 * wsum) { lo[m] = a; hi[m] = b; m++; }
    }
    return m;
}

/* the first grid point of the edges (N equal steps each, both ends included) later than t, or -1 */
static double sd_grid_after(double t, double ts, const double *lo, const double *hi, int m, int n)
{
    double k = floor(t / ts), best = -1.0;
    int i, p;
    for (p = 0; p < 2; p++)
        for (i = 0; i < m; i++) {
            double a = (k + p) * ts + lo[i], h = (hi[i] - lo[i]) / n, j, g;
            if (a + (hi[i] - lo[i]) <= t) continue;
            j = a > t ? 0.0 : floor((t - a) / h) + 1.0;
            g = a + j * h;
            if (g <= t) g = a + (j + 1.0) * h;
            if (g <= a + (hi[i] - lo[i]) * (1.0 + 1e-12) && (best < 0.0 || g < best)) best = g;
        }
    return best;
}

/* the next grid point after the last accepted time point as a temporary breakpoint (ngspice backs
   the step up to it when this trial passed it), else the next after this trial */
static void sd_ramp_breakpoint(ARGS, int J)
{
    double ts = PARAM(ts), lo[SD_MAX_EDGES], hi[SD_MAX_EDGES], g, guard = SD_GUARD * ts;
    int m, n = PARAM_NULL(ramp_steps) ? 0 : PARAM(ramp_steps);
    if (n <= 0 || ANALYSIS != MIF_TRAN || !PORT_NULL(ph) || TIME <= 0.0) return;
    m = sd_edges(mif_private, J, lo, hi);
    if (m == 0) return;
    g = sd_grid_after(T(1) + guard, ts, lo, hi, m, n);
    if (g > 0.0 && fabs(g - TIME) <= guard) g = sd_grid_after(TIME + guard, ts, lo, hi, m, n);
    if (g > 0.0) cm_analog_set_temp_bkpt(g);
}

/* does any channel have filter states (flt_n > 0)? Lead-only loops give flt_n = [0 ..] and one
   0 in each of flt_a, flt_bx, flt_bv, flt_c, u0 (XSPICE refuses an unset array parameter
   without a default, and a defaulted one must be sized by a port) */
static int sd_has_filter(ARGS)
{
    int c;
    if (PARAM_NULL(flt_n)) return 0;
    for (c = 0; c < PARAM_SIZE(flt_n); c++)
        if (PARAM(flt_n[c]) > 0) return 1;
    return 0;
}

/* sum over the channels of flt_n^power (the filter states: power 1; their A matrices: 2) */
static int sd_filter_size(ARGS, int C, int power)
{
    int c, n = 0;
    if (!sd_has_filter(mif_private)) return 0;
    for (c = 0; c < C && c < PARAM_SIZE(flt_n); c++) {
        int k = PARAM(flt_n[c]) > 0 ? PARAM(flt_n[c]) : 0;
        n += power == 2 ? k * k : k;
    }
    return n;
}

/* one channel's state-space loop filter at the latch (filters.py): the decision variable
   y = c.u + d x + dither from the states before the update, then u <- A u + bx x + bv v with
   v = +-1 the bit just decided; off / offa: the channel's first entry in flt_bx.. / flt_a */
static double sd_filter(ARGS, double *u, int c, int k, int off, int offa, double x, double dither)
{
    double y = PARAM(flt_d[c]) * x + dither, v, next[SD_MAX_K];
    int i, j;
    for (i = 0; i < k; i++) y += PARAM(flt_c[off + i]) * u[i];
    v = y > 0.0 ? 1.0 : -1.0;
    for (i = 0; i < k; i++) {
        next[i] = PARAM(flt_bx[off + i]) * x + PARAM(flt_bv[off + i]) * v;
        for (j = 0; j < k; j++) next[i] += PARAM(flt_a[offa + i * k + j]) * u[j];
    }
    for (i = 0; i < k; i++) u[i] = next[i];
    return y;
}

/* the parameter and port sizes agree (checked at every call: a mismatch would index past an
   array; the message is sent once, at INIT) */
static int sd_sizes_ok(ARGS, int C, int E, int J)
{
    char msg[200];
    const char *bad = NULL;
    if (PARAM_SIZE(sel) != E * C) bad = "sel must have (drv size) x (ca size) entries";
    else if (PARAM_SIZE(ph_sense) != J || PARAM_SIZE(ph_fb) != J) bad = "ph_sense and ph_fb need one entry per phase";
    else if (PORT_NULL(ph) && PARAM_SIZE(ph_pulse) % 7 != 0)
        bad = "without ph inputs, ph_pulse must give 7 numbers (v1 v2 td tr tf pw per) per phase";
    else if (PARAM_SIZE(dither_amp) != C || PARAM_SIZE(dither_step) != C || PARAM_SIZE(cur0) != C
             || PARAM_SIZE(prev0) != C || PARAM_SIZE(b0) != C)
        bad = "dither_amp, dither_step, cur0, prev0 and b0 need one entry per ca input";
    else if (!PARAM_NULL(leads) && PARAM_SIZE(leads) != C)
        bad = "leads needs one entry per ca input";
    else if (!PARAM_NULL(flt_x0) && PARAM_SIZE(flt_x0) != C)
        bad = "flt_x0 needs one entry per ca input";
    else if (sd_has_filter(mif_private) && PARAM_SIZE(flt_n) != C) bad = "flt_n needs one entry per ca input";
    else if (sd_has_filter(mif_private) && (PARAM_NULL(flt_a) || PARAM_NULL(flt_bx) || PARAM_NULL(flt_bv) || PARAM_NULL(flt_c)
                                    || PARAM_NULL(flt_d) || PARAM_SIZE(flt_a) != sd_filter_size(mif_private, C, 2)
                                    || PARAM_SIZE(flt_bx) != sd_filter_size(mif_private, C, 1)
                                    || PARAM_SIZE(flt_bv) != PARAM_SIZE(flt_bx) || PARAM_SIZE(flt_c) != PARAM_SIZE(flt_bx)
                                    || PARAM_SIZE(flt_d) != C
                                    || PARAM_SIZE(u0) != PARAM_SIZE(flt_bx)))
        bad = "flt_a needs sum flt_n^2 entries, flt_bx, flt_bv, flt_c (and u0) sum flt_n, flt_d one per ca input";
    else if (!PORT_NULL(u) && PORT_SIZE(u) != sd_filter_size(mif_private, C, 1))
        bad = "u needs one node per filter state (sum flt_n)";
    else if ((!PORT_NULL(b) && PORT_SIZE(b) != C) || (!PORT_NULL(cur) && PORT_SIZE(cur) != C)
             || (!PORT_NULL(prev) && PORT_SIZE(prev) != C))
        bad = "b, cur and prev need one node per ca input";
    if (!bad) return 1;
    if (INIT) {
        snprintf(msg, sizeof msg, "netgen_sdloop: %s", bad);
        cm_message_send(msg);
    }
    return 0;
}

static void sd_initial(ARGS, double *s, int C)
{
    int c;
    s[ST_T] = TIME;
    for (c = 0; c < C; c++) {
        s[ST_HEAD + c] = INPUT(ca[c]);
        s[ST_HEAD + C + c] = PARAM(cur0[c]);
        s[ST_HEAD + 2 * C + c] = PARAM(prev0[c]);
        s[ST_HEAD + 3 * C + c] = PARAM(b0[c]) > 0.5 ? 1.0 : 0.0;
    }
    for (c = 0; c < sd_filter_size(mif_private, C, 1); c++)
        s[ST_HEAD + 4 * C + c] = PARAM(u0[c]);
}

/* the events of (old time, TIME] in order, applied to s (a copy of the accepted state); returns
   per channel d cur / d ca(TIME) (the interpolation weight of a sample taken in this step) */
static void sd_events(ARGS, const double *old, double *s, int C, double *dcur)
{
    double ts = PARAM(ts), t1 = old[ST_T], t0 = TIME, lead = PARAM_NULL(lead) ? 0.0 : PARAM(lead);
    double start = PARAM_NULL(start) ? 0.0 : PARAM(start);
    double ps = PARAM(t_sample), pl = PARAM(t_latch);
    double first = ps < pl ? ps : pl, second = ps < pl ? pl : ps;
    long k, k1 = (long) floor(t1 / ts), k0 = (long) floor(t0 / ts);
    int c, j;
    for (c = 0; c < C; c++) dcur[c] = 0.0;
    for (k = k1; k <= k0; k++) {
        for (j = 0; j < 2; j++) {
            double ph = j ? second : first, te = (k + ph) * ts;
            if (!(te > t1 && te <= t0)) continue;
            if (ph == ps) {
                double w = (te - t1) / (t0 - t1);
                for (c = 0; c < C; c++) {
                    s[ST_HEAD + 2 * C + c] = s[ST_HEAD + C + c];
                    s[ST_HEAD + C + c] = old[ST_HEAD + c] + w * (INPUT(ca[c]) - old[ST_HEAD + c]);
                    dcur[c] = w;
                }
            }
            if (ph == pl) {
                int off = 0, offa = 0;
                for (c = 0; c < C; c++) {
                    int nk = sd_has_filter(mif_private) ? PARAM(flt_n[c]) : 0;
                    double dither = PARAM(dither_amp[c]) * sin(PARAM(dither_step[c]) * ((double) k + start));
                    double y = nk > 0 ? sd_filter(mif_private, s + ST_HEAD + 4 * C + off, c, nk, off, offa,
                                                  s[ST_HEAD + C + c] - (PARAM_NULL(flt_x0) ? 0.0 : PARAM(flt_x0[c])), dither)
                                      : (PARAM_NULL(leads) ? lead : PARAM(leads[c])) * s[ST_HEAD + 2 * C + c]
                                        - s[ST_HEAD + C + c] + dither;
                    if (nk > 0) { off += nk; offa += nk * nk; }
                    s[ST_HEAD + 3 * C + c] = y > 0.0 ? 1.0 : 0.0;
                    if (ph == ps) dcur[c] = 0.0;      /* a hard decision: no partial */
                }
            }
        }
    }
    for (c = 0; c < C; c++) s[ST_HEAD + c] = INPUT(ca[c]);
    s[ST_T] = t0;
}

/* the filter states on the u port (a segment restarted at t = 0 sets them again through u0) */
static void sd_state_outputs(ARGS, const double *s, int C, int J)
{
    int i, j, own = PORT_NULL(ph);
    if (PORT_NULL(u)) return;
    for (i = 0; i < PORT_SIZE(u); i++) {
        OUTPUT(u[i]) = s[ST_HEAD + 4 * C + i];
        for (j = 0; j < C; j++) {
            if (ANALYSIS == MIF_AC) {
                Mif_Complex_t zero = {0.0, 0.0};
                AC_GAIN(u[i], ca[j]) = zero;
            } else {
                PARTIAL(u[i], ca[j]) = 0.0;
            }
        }
        for (j = 0; j < J && !own; j++) {
            if (ANALYSIS == MIF_AC) {
                Mif_Complex_t zero = {0.0, 0.0};
                AC_GAIN(u[i], ph[j]) = zero;
            } else {
                PARTIAL(u[i], ph[j]) = 0.0;
            }
        }
    }
}

static void sd_outputs(ARGS, const double *s, const double *dcur, int C, int E, int J)
{
    const double *bit = s + ST_HEAD + 3 * C;
    double sense = 0.0, fb = 0.0, fb_step;
    int e, c, j, own = PORT_NULL(ph);
    fb_step = sd_step(mif_private, ANALYSIS == MIF_TRAN ? TIME : 0.0);
    for (j = 0; j < J; j++) {
        double v;
        if (own) {
            double p[7];
            int q;
            for (q = 0; q < 7; q++) p[q] = PARAM(ph_pulse[7 * j + q]);
            v = sd_pulse(p, ANALYSIS == MIF_TRAN ? TIME : 0.0);
        } else {
            v = INPUT(ph[j]);
        }
        sense += PARAM(ph_sense[j]) * v;
        fb += PARAM(ph_fb[j]) * v;
    }
    for (e = 0; e < E; e++) {
        double g = 1.0;
        int fed = 0;
        for (c = 0; c < C; c++) {
            int need = PARAM(sel[e * C + c]);
            if (need > 0) g *= bit[c];
            else if (need < 0) g *= 1.0 - bit[c];
            if (need) fed = 1;
        }
        if (!fed) g = 0.0;
        OUTPUT(drv[e]) = sense + g * (fb + fb_step);
        for (j = 0; j < J && !own; j++) {
            double p = PARAM(ph_sense[j]) + g * PARAM(ph_fb[j]);
            if (ANALYSIS == MIF_AC) {
                Mif_Complex_t gain = {p, 0.0};
                AC_GAIN(drv[e], ph[j]) = gain;
            } else {
                PARTIAL(drv[e], ph[j]) = p;
            }
        }
        for (c = 0; c < C; c++) {
            if (ANALYSIS == MIF_AC) {
                Mif_Complex_t zero = {0.0, 0.0};
                AC_GAIN(drv[e], ca[c]) = zero;
            } else {
                PARTIAL(drv[e], ca[c]) = 0.0;
            }
        }
    }
    for (c = 0; c < C; c++) {
        int i;
        if (!PORT_NULL(b)) OUTPUT(b[c]) = bit[c];
        if (!PORT_NULL(cur)) OUTPUT(cur[c]) = s[ST_HEAD + C + c];
        if (!PORT_NULL(prev)) OUTPUT(prev[c]) = s[ST_HEAD + 2 * C + c];
        for (i = 0; i < C; i++) {
            double dc = (i == c) ? dcur[c] : 0.0;
            if (ANALYSIS == MIF_AC) {
                Mif_Complex_t zero = {0.0, 0.0};
                if (!PORT_NULL(b)) AC_GAIN(b[c], ca[i]) = zero;
                if (!PORT_NULL(cur)) AC_GAIN(cur[c], ca[i]) = zero;
                if (!PORT_NULL(prev)) AC_GAIN(prev[c], ca[i]) = zero;
            } else {
                if (!PORT_NULL(b)) PARTIAL(b[c], ca[i]) = 0.0;
                if (!PORT_NULL(cur)) PARTIAL(cur[c], ca[i]) = dc;
                if (!PORT_NULL(prev)) PARTIAL(prev[c], ca[i]) = 0.0;
            }
        }
        for (i = 0; i < J && !own; i++) {
            if (ANALYSIS == MIF_AC) {
                Mif_Complex_t zero = {0.0, 0.0};
                if (!PORT_NULL(b)) AC_GAIN(b[c], ph[i]) = zero;
                if (!PORT_NULL(cur)) AC_GAIN(cur[c], ph[i]) = zero;
                if (!PORT_NULL(prev)) AC_GAIN(prev[c], ph[i]) = zero;
            } else {
                if (!PORT_NULL(b)) PARTIAL(b[c], ph[i]) = 0.0;
                if (!PORT_NULL(cur)) PARTIAL(cur[c], ph[i]) = 0.0;
                if (!PORT_NULL(prev)) PARTIAL(prev[c], ph[i]) = 0.0;
            }
        }
    }
}

void cm_netgen_sdloop(ARGS)
{
    int C = PORT_SIZE(ca), E = PORT_SIZE(drv);
    int J = PORT_NULL(ph) ? PARAM_SIZE(ph_pulse) / 7 : PORT_SIZE(ph);
    double *s, *old, dcur[64];
    int c, n;
    if (C > 64) {
        cm_message_send("netgen_sdloop: at most 64 channels");
        return;
    }
    if (!sd_sizes_ok(mif_private, C, E, J)) return;
    for (c = 0; sd_has_filter(mif_private) && c < C; c++)
        if (PARAM(flt_n[c]) > SD_MAX_K) {
            if (INIT) cm_message_send("netgen_sdloop: at most 8 filter states per channel (flt_n)");
            return;
        }
    n = ST_HEAD + 4 * C + sd_filter_size(mif_private, C, 1);
    if (INIT) cm_analog_alloc(0, (int) sizeof(double) * n);
    s = (double *) cm_analog_get_ptr(0, 0);
    old = (double *) cm_analog_get_ptr(0, 1);
    memset(dcur, 0, sizeof dcur);
    if (INIT || ANALYSIS != MIF_TRAN || TIME == 0.0) {
        if (ANALYSIS != MIF_AC) {
            sd_initial(mif_private, s, C);
            memcpy(old, s, sizeof(double) * n);
        }
    } else {
        memcpy(s, old, sizeof(double) * n);
        sd_events(mif_private, old, s, C, dcur);
    }
    sd_step_breakpoint(mif_private);
    sd_ramp_breakpoint(mif_private, J);
    sd_outputs(mif_private, s, dcur, C, E, J);
    sd_state_outputs(mif_private, s, C, J);
}
