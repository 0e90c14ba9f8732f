/* netgen electrostatic core (ifspec.ifs): the plate terms of a netgen macromodel in one compiled
   instance. Per plate term k of electrode e(k):
     P_k(xs)  the fitted polynomial (affine part as a dense row, higher monomials listed),
     P_eff    P above the knee, floor + span exp((P - knee)/span) below (C1 contact clamp),
     g_k = 1/P_eff,  s_k = dP_eff/dP.
   Outputs (either port may be NULL, so one instance can stamp only what it drives):
     c[e] = sum_{k in e} g_k - c0[e]      into a 1 ohm node: C_e(q)/c_ref - C_e(0)/c_ref
     f[v] = -fgain[v] sum_k cref[e] (V_e - V_plate)^2 g_k^2 s_k dP_k/dxs_v  + contact stops
   XSPICE current outputs draw OUTPUT from their node, so f and c are written negated. */

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    int N, E, K, S, M2;
    int *elec, *mt, *me, *kstart;
    double *p0, *A, *mc, *knee, *fl, *cref, *c0, *fgain, *sa, *sr, *sgain, delta, damp;
    double *Dt, *ta, *tb, *tc, *th;
    double *P, *dP, *d2P, *x, *u, *v, *F, *dFdx, *dFdu, *dFdv, *C, *dCdx;
} es_t;

static void es_free(ARGS, Mif_Callback_Reason_t reason)
{
    if (reason == MIF_CB_DESTROY && STATIC_VAR(work)) {
        es_t *w = (es_t *) STATIC_VAR(work);
        free(w->elec); free(w->kstart); free(w->mt); free(w->me); free(w->p0); free(w);
        STATIC_VAR(work) = NULL;
    }
}

static es_t *es_init(ARGS)
{
    int N = PORT_SIZE(xs), E = PARAM_SIZE(cref), K = PARAM_SIZE(knee), M = PARAM_SIZE(mono_coef);
    int i, k, m, n2 = 0;
    es_t *w = (es_t *) calloc(1, sizeof(es_t));
    if (!w) {
        cm_message_send("netgen_es: out of memory");
        return NULL;
    }
    w->N = N; w->E = E; w->K = K; w->S = PARAM_SIZE(stop_a) / N;
    for (m = 0; m < M; m++) {
        int deg = 0;
        for (i = 0; i < N; i++) deg += PARAM(mono_exp[m * N + i]);
        if (deg > 1) n2++;
    }
    w->M2 = n2;
    w->elec = (int *) calloc((size_t) K, sizeof(int));
    w->kstart = (int *) calloc((size_t) E + 1, sizeof(int));
    w->mt = (int *) calloc((size_t) n2 + 1, sizeof(int));
    w->me = (int *) calloc((size_t) (n2 + 1) * N, sizeof(int));
    {   /* one block of doubles: the constants, then the work arrays */
        int S = w->S;
        size_t sizes[] = {K, K * N, n2, K, K, E, E, N, S * N, S * N, S * N, N * K, K, K, K, K,
                          K, K * N, K * N * N, N, N, E, N, N * N, N * N, N * E, E, E * N};
        double **slots[] = {&w->p0, &w->A, &w->mc, &w->knee, &w->fl, &w->cref, &w->c0, &w->fgain,
                            &w->sa, &w->sr, &w->sgain, &w->Dt, &w->ta, &w->tb, &w->tc, &w->th,
                            &w->P, &w->dP, &w->d2P, &w->x, &w->u, &w->v, &w->F, &w->dFdx, &w->dFdu,
                            &w->dFdv, &w->C, &w->dCdx};
        size_t n = sizeof(sizes) / sizeof(sizes[0]), total = 0, q;
        double *d;
        for (q = 0; q < n; q++) total += sizes[q];
        d = (double *) calloc(total, sizeof(double));
        if (!d || !w->elec || !w->kstart || !w->mt || !w->me) {
            cm_message_send("netgen_es: out of memory");
            return NULL;
        }
        for (q = 0; q < n; q++) { *slots[q] = d; d += sizes[q]; }
    }
    for (k = 0; k < K; k++) {
        w->elec[k] = PARAM(term_elec[k]); w->knee[k] = PARAM(knee[k]); w->fl[k] = PARAM(floor[k]);
    }
    for (k = 0; k < K; k++) {                       /* terms come grouped by electrode: kstart[e].. */
        if (k > 0 && w->elec[k] < w->elec[k - 1]) w->kstart[0] = -1;
        w->kstart[w->elec[k] + 1] = k + 1;
    }
    for (i = 1; i <= E; i++) if (w->kstart[i] < w->kstart[i - 1]) w->kstart[i] = w->kstart[i - 1];
    for (i = 0; i < E; i++) { w->cref[i] = PARAM(cref[i]); w->c0[i] = PARAM(c0[i]); }
    for (i = 0; i < N; i++) w->fgain[i] = PARAM(fgain[i]);
    for (i = 0; i < w->S * N; i++) {
        w->sa[i] = PARAM(stop_a[i]); w->sr[i] = PARAM(stop_rate[i]); w->sgain[i] = PARAM(stop_gain[i]);
    }
    w->delta = PARAM(stop_delta); w->damp = PARAM(stop_damp);
    for (m = 0, n2 = 0; m < M; m++) {
        int t = PARAM(mono_term[m]), deg = 0, at = -1;
        double c = PARAM(mono_coef[m]);
        for (i = 0; i < N; i++) { int e = PARAM(mono_exp[m * N + i]); deg += e; if (e) at = i; }
        if (deg == 0) w->p0[t] += c;
        else if (deg == 1) w->A[at * K + t] += c;
        else {
            w->mt[n2] = t; w->mc[n2] = c;
            for (i = 0; i < N; i++) w->me[n2 * N + i] = PARAM(mono_exp[m * N + i]);
            n2++;
        }
    }
    return w;
}

/* value, gradient and Hessian of the higher monomials, added to P, dP, d2P */
static void es_higher(es_t *w)
{
    int N = w->N, m, i, j, l;
    for (m = 0; m < w->M2; m++) {
        const int *e = w->me + m * N;
        int t = w->mt[m];
        double val = w->mc[m];
        for (l = 0; l < N; l++) if (e[l]) val *= pow(w->x[l], e[l]);
        w->P[t] += val;
        for (i = 0; i < N; i++) {
            if (!e[i]) continue;
            double d = w->mc[m] * e[i];
            for (l = 0; l < N; l++) if (e[l]) d *= pow(w->x[l], e[l] - (l == i));
            w->dP[t * N + i] += d;
            for (j = 0; j < N; j++) {
                int ej = e[j] - (j == i);
                if (ej <= 0) continue;
                double h = w->mc[m] * e[i] * ej;
                for (l = 0; l < N; l++) {
                    int el = e[l] - (l == i) - (l == j);
                    if (el) h *= pow(w->x[l], el);
                }
                w->d2P[(t * N + i) * N + j] += h;
            }
        }
    }
}

/* sum_k a[k] b[k] c[k] over n terms, four accumulators (vectorisable without -ffast-math) */
static double dot3(const double *a, const double *b, const double *c, int n)
{
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    int k = 0;
    for (; k + 4 <= n; k += 4) {
        s0 += a[k] * b[k] * c[k]; s1 += a[k + 1] * b[k + 1] * c[k + 1];
        s2 += a[k + 2] * b[k + 2] * c[k + 2]; s3 += a[k + 3] * b[k + 3] * c[k + 3];
    }
    for (; k < n; k++) s0 += a[k] * b[k] * c[k];
    return (s0 + s1) + (s2 + s3);
}

static double dot2(const double *a, const double *b, int n)
{
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    int k = 0;
    for (; k + 4 <= n; k += 4) {
        s0 += a[k] * b[k]; s1 += a[k + 1] * b[k + 1]; s2 += a[k + 2] * b[k + 2]; s3 += a[k + 3] * b[k + 3];
    }
    for (; k < n; k++) s0 += a[k] * b[k];
    return (s0 + s1) + (s2 + s3);
}

void cm_netgen_es(ARGS)
{
    es_t *w;
    int N, E, K, i, j, k, l, e;
    int want_f = !PORT_NULL(f), want_c = !PORT_NULL(c);

    if (INIT) {
        CALLBACK = es_free;
        STATIC_VAR(work) = es_init(mif_private);
    }
    w = (es_t *) STATIC_VAR(work);
    if (!w) return;
    N = w->N; E = w->E; K = w->K;
    if (w->kstart[0] < 0) {
        cm_message_send("netgen_es: term_elec must list the terms grouped by electrode (0, 0, 1, 1, ...)");
        return;
    }
    if ((want_f && (PORT_NULL(ve) || PORT_NULL(us) || PORT_SIZE(ve) != E || PORT_SIZE(us) != N || PORT_SIZE(f) != N))
        || (want_c && PORT_SIZE(c) != E)) {
        cm_message_send("netgen_es: port sizes do not match the model (xs, us, f: coordinates; ve, c: electrodes)");
        return;
    }
    for (i = 0; i < N; i++) w->x[i] = INPUT(xs[i]);
    if (want_f) {
        for (i = 0; i < N; i++) w->u[i] = INPUT(us[i]);
        for (e = 0; e < E; e++) w->v[e] = INPUT(ve[e]);
    }
    /* P_k = p0_k + A_k . x; the gradient rows Dt[i][k] (N x K) are A^T, plus the higher monomials */
    for (k = 0; k < K; k++) w->P[k] = w->p0[k];
    for (i = 0; i < N; i++) {
        const double *a = w->A + i * K;
        double xi = w->x[i];
        for (k = 0; k < K; k++) w->P[k] += a[k] * xi;
    }
    if (w->M2) {
        memset(w->dP, 0, sizeof(double) * K * N);
        memset(w->d2P, 0, sizeof(double) * K * N * N);
        es_higher(w);
        for (i = 0; i < N; i++) for (k = 0; k < K; k++) w->Dt[i * K + k] = w->A[i * K + k] + w->dP[k * N + i];
    }
    /* per term: g = 1/P_eff, th = g^2 s (dC/dP up to sign), ta = cref V^2 d(g^2 s)/dP, tb = cref V^2 g^2 s,
       tc = 2 cref V g^2 s */
    for (k = 0; k < K; k++) {
        double knee = w->knee[k], fl = w->fl[k], p = w->P[k], g, s, h, dh;
        if (knee > 0.0 && p <= knee) {              /* contact clamp, C1 at the knee */
            double span = knee - fl, ex = exp((p - knee) / span);
            g = 1.0 / (fl + span * ex); s = ex;
            h = g * (1.0 - fl * g) / span;          /* g^2 s */
            dh = -(1.0 - 2.0 * fl * g) * g * g * s / span;
        } else {
            g = 1.0 / p; h = g * g; dh = -2.0 * g * h;
        }
        w->P[k] = g;                                /* P is not needed again: keep g there */
        w->th[k] = h;
        if (want_f) {
            e = w->elec[k];
            double cv = w->cref[e] * w->v[e];
            w->tb[k] = cv * w->v[e] * h; w->ta[k] = cv * w->v[e] * dh; w->tc[k] = 2.0 * cv * h;
        }
    }
    const double *Dt = w->M2 ? w->Dt : w->A;
    if (want_c) {
        for (e = 0; e < E; e++) w->C[e] = -w->c0[e];
        for (k = 0; k < K; k++) w->C[w->elec[k]] += w->P[k];
        for (e = 0; e < E; e++) {
            int k0 = w->kstart[e], nk = w->kstart[e + 1] - k0;
            for (i = 0; i < N; i++) w->dCdx[e * N + i] = -dot2(w->th + k0, Dt + i * K + k0, nk);
        }
    }
    if (want_f) {
        /* F_i = -fgain_i sum_k tb_k D_ik;  dF_i/dx_l = -fgain_i sum_k (ta_k D_ik D_lk + tb_k d2P_kil);
           dF_i/dV_e = -fgain_i sum_{k in e} tc_k D_ik */
        for (i = 0; i < N; i++) {
            const double *di = Dt + i * K;
            double gi = -w->fgain[i];
            w->F[i] = gi * dot2(w->tb, di, K);
            for (l = i; l < N; l++) {                   /* the sum is symmetric in i, l */
                double sum = dot3(w->ta, di, Dt + l * K, K);
                w->dFdx[i * N + l] = gi * sum;
                w->dFdx[l * N + i] = -w->fgain[l] * sum;
            }
            for (e = 0; e < E; e++) {
                int k0 = w->kstart[e];
                w->dFdv[i * E + e] = gi * dot2(w->tc + k0, di + k0, w->kstart[e + 1] - k0);
            }
        }
        if (w->M2) for (k = 0; k < K; k++) {
            const double *h2 = w->d2P + k * N * N;
            for (i = 0; i < N; i++) for (l = 0; l < N; l++) w->dFdx[i * N + l] -= w->fgain[i] * w->tb[k] * h2[i * N + l];
        }
        memset(w->dFdu, 0, sizeof(double) * N * N);
        /* contact stops: penalty spring-damper */
        double delta = w->delta, damp = w->damp;
        for (j = 0; j < w->S; j++) {
            const double *a = w->sa + j * N, *r8 = w->sr + j * N, *sg8 = w->sgain + j * N;
            double sg = -1.0, rate = 0.0;
            for (i = 0; i < N; i++) { sg += a[i] * w->x[i]; rate += r8[i] * w->u[i]; }
            if (sg <= 0.0) continue;
            double r = sg < delta ? sg : delta, dr = sg < delta ? 1.0 : 0.0;
            double sf = (r * r * 0.5 / delta + (sg > delta ? sg - delta : 0.0)) / delta + damp * r * rate;
            double dsf = (r * dr / delta + (sg > delta ? 1.0 : 0.0)) / delta + damp * dr * rate;
            for (i = 0; i < N; i++) {
                if (sg8[i] == 0.0) continue;
                w->F[i] += sg8[i] * sf;
                for (l = 0; l < N; l++) {
                    w->dFdx[i * N + l] += sg8[i] * dsf * a[l];
                    w->dFdu[i * N + l] += sg8[i] * damp * r * r8[l];
                }
            }
        }
    }
    if (ANALYSIS != MIF_AC) {
        if (want_f) for (i = 0; i < N; i++) {
            OUTPUT(f[i]) = -w->F[i];
            for (l = 0; l < N; l++) {
                PARTIAL(f[i], xs[l]) = -w->dFdx[i * N + l];
                PARTIAL(f[i], us[l]) = -w->dFdu[i * N + l];
            }
            for (e = 0; e < E; e++) PARTIAL(f[i], ve[e]) = -w->dFdv[i * E + e];
        }
        if (want_c) for (e = 0; e < E; e++) {
            OUTPUT(c[e]) = -w->C[e];
            for (l = 0; l < N; l++) PARTIAL(c[e], xs[l]) = -w->dCdx[e * N + l];
        }
    } else {
        Complex_t z;
        z.imag = 0.0;
        if (want_f) for (i = 0; i < N; i++) {
            for (l = 0; l < N; l++) {
                z.real = -w->dFdx[i * N + l]; AC_GAIN(f[i], xs[l]) = z;
                z.real = -w->dFdu[i * N + l]; AC_GAIN(f[i], us[l]) = z;
            }
            for (e = 0; e < E; e++) { z.real = -w->dFdv[i * E + e]; AC_GAIN(f[i], ve[e]) = z; }
        }
        if (want_c) for (e = 0; e < E; e++) for (l = 0; l < N; l++) {
            z.real = -w->dCdx[e * N + l]; AC_GAIN(c[e], xs[l]) = z;
        }
    }
}
