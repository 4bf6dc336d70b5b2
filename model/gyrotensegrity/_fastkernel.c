/* Compiled kernel of gyrotensegrity.fast (optional; the numpy path is the fallback).
 *
 * rhs(consts, dims, x, u, out, work) -> status evaluates the dense formulation documented
 * in fast.py for one state; jacobian(consts, dims, state, acc, J, work) -> status gives the
 * accelerations and their closed-form Jacobian (fast_jacobian.py, dense path without joints);
 * rig_rhs(consts, dims, x, u, out, work) the rig-fidelity model's dx/dt (fast_rig.py). All
 * arrays are contiguous float64 buffers laid out by fast.py (_kernel_constants); dims is an int64
 * buffer [m, beta, alpha, n_w, n_tq, c_u, diagonal]. Status 0 is success; k > 0 means the
 * constraint system lost positive definiteness at pivot k - 1 (singular geometry).
 * No Python objects are touched between argument parsing and return.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

typedef struct {
    const double *EE_T, *off, *k_s, *c_s, *w2b, *tsel, *smask, *tgain, *WU, *Ef, *Minv, *MinvET,
        *EMinv, *Y, *Pu, *PuMinv, *X, *A3;
} Consts;

/* one member per line: its pointer and the size it takes */
// clang-format off
static void layout(const double *c, const int64_t *d, Consts *k)
{
    int64_t m = d[0], beta = d[1], alpha = d[2], nw = d[3], ntq = d[4], cu = d[5];
    int64_t K = beta + alpha;
    k->EE_T = c; c += m * K;
    k->off = c; c += 3 * K;
    k->k_s = c; c += alpha;
    k->c_s = c; c += alpha;
    k->w2b = c; c += nw * beta;
    k->tsel = c; c += ntq * nw;
    k->smask = c; c += nw;
    k->tgain = c; c += nw * ntq;
    k->WU = c; c += 3 * m;
    k->Ef = c; c += K * m;
    k->Minv = c; c += m * m;
    k->MinvET = c; c += m * beta;
    k->EMinv = c; c += beta * m;
    k->Y = c; c += beta * beta;
    k->Pu = c; c += m * cu;
    k->PuMinv = c; c += cu * m;
    k->X = c; c += cu * beta;
    k->A3 = c;
}
// clang-format on

/* In-place Cholesky factor of the SPD matrix A (n x n, row-major; lower triangle). A pivot
 * that falls below PIVOT_RTOL times its diagonal entry (or is not finite) means the
 * constraints are dependent to working precision: the index of that row + 1 is returned. */
#define PIVOT_RTOL 1e-12
static int64_t cholesky_factor(double* A, int64_t n) {
    for (int64_t j = 0; j < n; j++) {
        double d = A[j * n + j], diag = d;
        for (int64_t k = 0; k < j; k++) d -= A[j * n + k] * A[j * n + k];
        if (!(d > PIVOT_RTOL * diag) || !isfinite(d)) return j + 1;
        d = sqrt(d);
        A[j * n + j] = d;
        for (int64_t i = j + 1; i < n; i++) {
            double s = A[i * n + j];
            for (int64_t k = 0; k < j; k++) s -= A[i * n + k] * A[j * n + k];
            A[i * n + j] = s / d;
        }
    }
    return 0;
}

/* b <- A^-1 b (n entries) with A's Cholesky factor L in the lower triangle of the leading n x n
 * block of A (leading dimension ld): forward, then backward. */
static void cholesky_subst_ld(const double* A, int64_t ld, double* b, int64_t n) {
    for (int64_t i = 0; i < n; i++) {
        double s = b[i];
        for (int64_t k = 0; k < i; k++) s -= A[i * ld + k] * b[k];
        b[i] = s / A[i * ld + i];
    }
    for (int64_t i = n - 1; i >= 0; i--) {
        double s = b[i];
        for (int64_t k = i + 1; k < n; k++) s -= A[k * ld + i] * b[k];
        b[i] = s / A[i * ld + i];
    }
}

/* b <- A^-1 b with A's Cholesky factor L (lower triangle of A, n x n). */
static void cholesky_subst(const double* A, double* b, int64_t n) {
    cholesky_subst_ld(A, n, b, n);
}

/* Columns c0..c1-1 of B (n rows of leading dimension ld) <- A^-1 B with A's Cholesky factor L
 * (lower triangle of A, n x n): cholesky_subst on every column at once, a row at a time (the
 * Jacobian's thirty columns in one pass, not thirty). */
static void cholesky_subst_rows(const double* A, int64_t n, double* B, int64_t ld, int64_t c0,
                                int64_t c1) {
    for (int64_t i = 0; i < n; i++) {
        double *bi = B + i * ld, r = 1.0 / A[i * n + i];
        for (int64_t k = 0; k < i; k++)
            for (int64_t c = c0; c < c1; c++) bi[c] -= A[i * n + k] * B[k * ld + c];
        for (int64_t c = c0; c < c1; c++) bi[c] *= r;
    }
    for (int64_t i = n - 1; i >= 0; i--) {
        double *bi = B + i * ld, r = 1.0 / A[i * n + i];
        for (int64_t k = i + 1; k < n; k++)
            for (int64_t c = c0; c < c1; c++) bi[c] -= A[k * n + i] * B[k * ld + c];
        for (int64_t c = c0; c < c1; c++) bi[c] *= r;
    }
}

static int64_t cholesky_solve(double* A, double* b, int64_t n) {
    int64_t status = cholesky_factor(A, n);
    if (!status) cholesky_subst(A, b, n);
    return status;
}

/* Bar and string vectors (pos, 3 x K) and their rates (vel) of coordinates q, qd (3 x m). */
static void member_vectors(const Consts* k, const int64_t* d, const double* q, const double* qd,
                           double* pos, double* vel) {
    int64_t m = d[0], K = d[1] + d[2];
    for (int64_t r = 0; r < 3; r++) {
        for (int64_t j = 0; j < K; j++) {
            double p = k->off[r * K + j], v = 0.0;
            for (int64_t i = 0; i < m; i++) {
                p += q[r * m + i] * k->EE_T[i * K + j];
                v += qd[r * m + i] * k->EE_T[i * K + j];
            }
            pos[r * K + j] = p;
            vel[r * K + j] = v;
        }
    }
}

/* f0 = W U + cols Ef (3 x m): the reduced forces of the member force columns (3 x K). */
static void reduced_forces(const Consts* k, const int64_t* d, const double* cols, double* f0) {
    int64_t m = d[0], K = d[1] + d[2];
    for (int64_t r = 0; r < 3; r++) {
        for (int64_t i = 0; i < m; i++) {
            double s = k->WU[r * m + i];
            for (int64_t j = 0; j < K; j++) s += cols[r * K + j] * k->Ef[j * m + i];
            f0[r * m + i] = s;
        }
    }
}

static int64_t evaluate(const Consts* k, const int64_t* d, const double* x, const double* u,
                        double* out, double* w) {
    int64_t m = d[0], beta = d[1], alpha = d[2], nw = d[3], ntq = d[4], cu = d[5];
    int64_t diagonal = d[6], K = beta + alpha, nb = beta + 3 * cu;
    const double *q = x, *qd = x + 3 * m, *uw = u + alpha;
    double *pos = w, *vel = pos + 3 * K, *cols = vel + 3 * K, *f0 = cols + 3 * K;
    double *a = f0 + 3 * m, *b2 = a + 3 * m, *bd2 = b2 + beta, *gfac = bd2 + beta;
    double *omega = gfac + beta, *sol = omega + nw, *A = sol + nb;

    member_vectors(k, d, q, qd, pos, vel);
    for (int64_t i = 0; i < nw; i++) {
        double s = k->smask[i] * uw[i];
        for (int64_t t = 0; t < ntq; t++) s += x[6 * m + nw + t] * k->tsel[t * nw + i];
        omega[i] = s;
    }
    for (int64_t i = 0; i < beta; i++) {
        double g = 0.0;
        for (int64_t j = 0; j < nw; j++) g += omega[j] * k->w2b[j * beta + i];
        double b0 = pos[i], b1 = pos[K + i], bz = pos[2 * K + i];
        double d0 = vel[i], d1 = vel[K + i], dz = vel[2 * K + i];
        b2[i] = b0 * b0 + b1 * b1 + bz * bz;
        bd2[i] = d0 * d0 + d1 * d1 + dz * dz;
        cols[i] = g * (b1 * dz - bz * d1);
        cols[K + i] = g * (bz * d0 - b0 * dz);
        cols[2 * K + i] = g * (b0 * d1 - b1 * d0);
    }
    for (int64_t j = beta; j < K; j++) {
        double s0 = pos[j], s1 = pos[K + j], s2 = pos[2 * K + j];
        double s = sqrt(s0 * s0 + s1 * s1 + s2 * s2);
        double sdot = (s0 * vel[j] + s1 * vel[K + j] + s2 * vel[2 * K + j]) / s;
        double rest = u[j - beta];
        double tension = k->k_s[j - beta] * (s - rest) + k->c_s[j - beta] * sdot;
        double gamma = (s > rest && tension > 0.0) ? tension / s : 0.0;
        cols[j] = s0 * gamma;
        cols[K + j] = s1 * gamma;
        cols[2 * K + j] = s2 * gamma;
    }
    reduced_forces(k, d, cols, f0);
    for (int64_t r = 0; r < 3; r++) {
        for (int64_t i = 0; i < m; i++) {
            double s = 0.0;
            for (int64_t j = 0; j < m; j++) s += f0[r * m + j] * k->Minv[j * m + i];
            a[r * m + i] = s;
        }
    }
    /* bar rows: r_i = -|b_dot|^2 - b_i . (f0 M^-1 E^T)_i */
    for (int64_t i = 0; i < beta; i++) {
        double s = -bd2[i];
        for (int64_t r = 0; r < 3; r++) {
            double fe = 0.0;
            for (int64_t j = 0; j < m; j++) fe += f0[r * m + j] * k->MinvET[j * beta + i];
            s -= pos[r * K + i] * fe;
        }
        sol[i] = s;
    }
    if (diagonal) {
        for (int64_t i = 0; i < beta; i++) sol[i] /= k->Y[i * beta + i] * b2[i];
    } else {
        for (int64_t i = 0; i < beta; i++) {
            for (int64_t j = 0; j < beta; j++) {
                double bb =
                    pos[i] * pos[j] + pos[K + i] * pos[K + j] + pos[2 * K + i] * pos[2 * K + j];
                A[i * nb + j] = k->Y[i * beta + j] * bb;
            }
            for (int64_t r = 0; r < 3; r++) {
                for (int64_t c = 0; c < cu; c++) {
                    double z = pos[r * K + i] * k->X[c * beta + i];
                    A[i * nb + beta + r * cu + c] = z;
                    A[(beta + r * cu + c) * nb + i] = z;
                }
            }
        }
        for (int64_t i = 0; i < 3 * cu; i++)
            for (int64_t j = 0; j < 3 * cu; j++)
                A[(beta + i) * nb + beta + j] = k->A3[i * 3 * cu + j];
        for (int64_t r = 0; r < 3; r++) {
            for (int64_t c = 0; c < cu; c++) {
                double s = 0.0;
                for (int64_t j = 0; j < m; j++) s += a[r * m + j] * k->Pu[j * cu + c];
                sol[beta + r * cu + c] = -s;
            }
        }
        int64_t status = cholesky_solve(A, sol, nb);
        if (status) return status;
    }
    double* acc = out + 3 * m;
    for (int64_t r = 0; r < 3; r++) {
        for (int64_t j = 0; j < m; j++) {
            double s = a[r * m + j];
            for (int64_t i = 0; i < beta; i++) s += sol[i] * pos[r * K + i] * k->EMinv[i * m + j];
            for (int64_t c = 0; c < cu; c++) s += sol[beta + r * cu + c] * k->PuMinv[c * m + j];
            acc[r * m + j] = s;
        }
    }
    for (int64_t i = 0; i < 3 * m; i++) out[i] = qd[i];
    for (int64_t i = 0; i < nw; i++) out[6 * m + i] = omega[i];
    for (int64_t t = 0; t < ntq; t++) {
        double s = 0.0;
        for (int64_t i = 0; i < nw; i++) s += uw[i] * k->tgain[i * ntq + t];
        out[6 * m + nw + t] = s;
    }
    return 0;
}

/* Work entries jacobian() needs (doubles). */
static int64_t jacobian_work(const int64_t* d) {
    int64_t m = d[0], beta = d[1], alpha = d[2], nw = d[3];
    int64_t K = beta + alpha, D = 6 * m + nw + alpha;
    return 27 * K + 3 * m + 10 * beta + 3 * alpha + beta * beta + beta * m + (3 * m + beta) * D;
}

/* Per member, the derivative of its force column (bars: gyroscopic, strings: tension) with
 * respect to its vector (Dq, 3x3) and its rate (Dd, 3x3); strings also with respect to the
 * rest length (Dr, 3). Fills cols (3, K) and gxb = b x b_dot (3, beta). fast_jacobian.py
 * has the formulas. */
static void member_tangents(const Consts* k, const int64_t* d, const double* om, const double* rest,
                            const double* pos, const double* vel, double* cols, double* gxb,
                            double* Dq, double* Dd, double* Dr) {
    int64_t beta = d[1], alpha = d[2], nw = d[3], K = beta + alpha;
    for (int64_t i = 0; i < 9 * K; i++) Dq[i] = Dd[i] = 0.0;
    for (int64_t i = 0; i < beta; i++) {
        double phi = 0.0;
        for (int64_t j = 0; j < nw; j++) phi += om[j] * k->w2b[j * beta + i];
        double b[3] = {pos[i], pos[K + i], pos[2 * K + i]};
        double bd[3] = {vel[i], vel[K + i], vel[2 * K + i]};
        for (int64_t a = 0; a < 3; a++) {
            int64_t a1 = (a + 1) % 3, a2 = (a + 2) % 3;
            gxb[a * beta + i] = b[a1] * bd[a2] - b[a2] * bd[a1];
            cols[a * K + i] = phi * gxb[a * beta + i];
            /* [v]_x has -v[a2] at (a, a1) and +v[a1] at (a, a2): -phi [b_dot]_x, phi [b]_x */
            Dq[i * 9 + a * 3 + a1] = phi * bd[a2];
            Dq[i * 9 + a * 3 + a2] = -phi * bd[a1];
            Dd[i * 9 + a * 3 + a1] = -phi * b[a2];
            Dd[i * 9 + a * 3 + a2] = phi * b[a1];
        }
    }
    for (int64_t i = 0; i < alpha; i++) {
        int64_t j = beta + i;
        double S[3] = {pos[j], pos[K + j], pos[2 * K + j]};
        double Sd[3] = {vel[j], vel[K + j], vel[2 * K + j]};
        double s = sqrt(S[0] * S[0] + S[1] * S[1] + S[2] * S[2]), u[3];
        for (int64_t a = 0; a < 3; a++) u[a] = S[a] / s;
        double sdot = u[0] * Sd[0] + u[1] * Sd[1] + u[2] * Sd[2];
        double ks = k->k_s[i], cs = k->c_s[i];
        double t = ks * (s - rest[i]) + cs * sdot;
        int taut = s > rest[i] && t > 0.0;
        for (int64_t a = 0; a < 3; a++) {
            cols[a * K + j] = taut ? t * u[a] : 0.0;
            Dr[a * alpha + i] = taut ? -ks * u[a] : 0.0;
            if (!taut) continue;
            for (int64_t c = 0; c < 3; c++) {
                double uu = u[a] * u[c];
                Dq[j * 9 + a * 3 + c] =
                    (t / s) * ((a == c) - uu) + ks * uu + (cs / s) * u[a] * (Sd[c] - sdot * u[c]);
                Dd[j * 9 + a * 3 + c] = cs * uu;
            }
        }
    }
}

/* d f0 / d state (3 m x D, row-major): member blocks spread over the coordinates, wheel
 * spins, rest lengths. f0 = W U + cols Ef with Ef = [E; -E_s]. */
static void force_jacobian(const Consts* k, const int64_t* d, const double* gxb, const double* Dq,
                           const double* Dd, const double* Dr, double* Jf) {
    int64_t m = d[0], beta = d[1], alpha = d[2], nw = d[3];
    int64_t K = beta + alpha, D = 6 * m + nw + alpha;
    for (int64_t i = 0; i < 3 * m * D; i++) Jf[i] = 0.0;
    for (int64_t j = 0; j < K; j++) {
        for (int64_t a = 0; a < 3; a++) {
            for (int64_t lp = 0; lp < m; lp++) {
                double e = k->Ef[j * m + lp];
                if (e == 0.0) continue;
                double* row = Jf + (a * m + lp) * D;
                for (int64_t b = 0; b < 3; b++) {
                    double gq = e * Dq[j * 9 + a * 3 + b], gd = e * Dd[j * 9 + a * 3 + b];
                    for (int64_t l = 0; l < m; l++) {
                        double el = k->EE_T[l * K + j];
                        row[b * m + l] += gq * el;
                        row[3 * m + b * m + l] += gd * el;
                    }
                }
                if (j < beta) {
                    for (int64_t w = 0; w < nw; w++)
                        row[6 * m + w] += k->w2b[w * beta + j] * gxb[a * beta + j] * e;
                } else {
                    row[6 * m + nw + j - beta] += Dr[a * alpha + j - beta] * e;
                }
            }
        }
    }
}

/* Accelerations (3, m) and their Jacobian's columns c0..c1-1 (of 3 m x D; the others partial)
 * at state [q, q_dot, omega_w, rest] for the dense path without joints (fast_jacobian.py: the
 * derivation). Status as evaluate(). */
static int64_t jacobian_columns(const Consts* k, const int64_t* d, const double* x, double* acc,
                                double* J, double* w, int64_t c0, int64_t c1) {
    int64_t m = d[0], beta = d[1], alpha = d[2], nw = d[3];
    int64_t K = beta + alpha, D = 6 * m + nw + alpha;
    const double *q = x, *qd = x + 3 * m, *om = x + 6 * m, *rest = x + 6 * m + nw;
    double *pos = w, *vel = pos + 3 * K, *cols = vel + 3 * K, *Dq = cols + 3 * K;
    double *Dd = Dq + 9 * K, *f0 = Dd + 9 * K, *V = f0 + 3 * m, *gxb = V + 3 * beta;
    double *Dr = gxb + 3 * beta, *mu = Dr + 3 * alpha, *Z = mu + beta;
    double *P = Z + beta * beta, *YmuE = P + 3 * beta, *Jf = YmuE + beta * m;
    double* Jr = Jf + 3 * m * D;

    member_vectors(k, d, q, qd, pos, vel);
    member_tangents(k, d, om, rest, pos, vel, cols, gxb, Dq, Dd, Dr);
    force_jacobian(k, d, gxb, Dq, Dd, Dr, Jf);
    reduced_forces(k, d, cols, f0);
    /* a0 = f0 M^-1 (into acc, J) and V = f0 M^-1 E^T */
    for (int64_t r = 0; r < 3; r++) {
        for (int64_t j = 0; j < m; j++) {
            double s = 0.0, *row = J + (r * m + j) * D;
            for (int64_t c = 0; c < D; c++) row[c] = 0.0;
            for (int64_t i = 0; i < m; i++) {
                double g = k->Minv[i * m + j];
                s += f0[r * m + i] * g;
                const double* src = Jf + (r * m + i) * D;
                for (int64_t c = c0; c < c1; c++) row[c] += g * src[c];
            }
            acc[r * m + j] = s;
        }
        for (int64_t j = 0; j < beta; j++) {
            double s = 0.0;
            for (int64_t i = 0; i < m; i++) s += f0[r * m + i] * k->MinvET[i * beta + j];
            V[r * beta + j] = s;
        }
    }
    /* r_j = -|b_dot_j|^2 - b_j . V_j and its derivative */
    for (int64_t j = 0; j < beta; j++) {
        double s = 0.0, *row = Jr + j * D;
        for (int64_t c = 0; c < D; c++) row[c] = 0.0;
        for (int64_t a = 0; a < 3; a++) {
            double b = pos[a * K + j], bd = vel[a * K + j];
            s -= bd * bd + b * V[a * beta + j];
            for (int64_t i = 0; i < m; i++) {
                double g = -b * k->MinvET[i * beta + j];
                const double* src = Jf + (a * m + i) * D;
                for (int64_t c = c0; c < c1; c++) row[c] += g * src[c];
            }
            for (int64_t l = 0; l < m; l++) {
                double e = k->EE_T[l * K + j];
                row[a * m + l] -= V[a * beta + j] * e;
                row[3 * m + a * m + l] -= 2.0 * bd * e;
            }
        }
        mu[j] = s;
        for (int64_t i = 0; i < beta; i++) {
            double bb = 0.0;
            for (int64_t a = 0; a < 3; a++) bb += pos[a * K + j] * pos[a * K + i];
            Z[j * beta + i] = k->Y[j * beta + i] * bb;
        }
    }
    int64_t status = cholesky_factor(Z, beta);
    if (status) return status;
    cholesky_subst(Z, mu, beta);
    /* through the bars in Z: (dZ mu)_j = db_j . p_j + b_j . sum_i Y_ji mu_i db_i */
    for (int64_t j = 0; j < beta; j++) {
        for (int64_t a = 0; a < 3; a++) {
            double s = 0.0;
            for (int64_t i = 0; i < beta; i++) s += k->Y[j * beta + i] * mu[i] * pos[a * K + i];
            P[a * beta + j] = s;
        }
        for (int64_t l = 0; l < m; l++) {
            double s = 0.0;
            for (int64_t i = 0; i < beta; i++) s += k->Y[j * beta + i] * mu[i] * k->EE_T[l * K + i];
            YmuE[j * m + l] = s;
        }
        double* row = Jr + j * D;
        for (int64_t a = 0; a < 3; a++)
            for (int64_t l = 0; l < m; l++)
                row[a * m + l] -=
                    P[a * beta + j] * k->EE_T[l * K + j] + pos[a * K + j] * YmuE[j * m + l];
    }
    cholesky_subst_rows(Z, beta, Jr, D, c0, c1);
    /* z_ddot = a0 + (B mu^) E M^-1 */
    for (int64_t r = 0; r < 3; r++) {
        for (int64_t j = 0; j < m; j++) {
            double* row = J + (r * m + j) * D;
            for (int64_t i = 0; i < beta; i++) {
                double g = pos[r * K + i] * k->EMinv[i * m + j];
                acc[r * m + j] += mu[i] * g;
                const double* src = Jr + i * D;
                for (int64_t c = c0; c < c1; c++) row[c] += g * src[c];
            }
            for (int64_t l = 0; l < m; l++) {
                double s = 0.0;
                for (int64_t i = 0; i < beta; i++)
                    s += mu[i] * k->EE_T[l * K + i] * k->EMinv[i * m + j];
                row[r * m + l] += s;
            }
        }
    }
    return 0;
}

/* Accelerations (3, m) and their whole Jacobian (3 m x D): jacobian_columns over every column. */
static int64_t jacobian(const Consts* k, const int64_t* d, const double* x, double* acc, double* J,
                        double* w) {
    return jacobian_columns(k, d, x, acc, J, w, 0, 6 * d[0] + d[3] + d[2]);
}

/* ---- The estimator's lean prediction step (gyrohost.estimator.process_model, "lean") ----
 * State z = [q, q_dot, omega_w, rest] (D = 6 m + n_w + alpha entries), then n - D entries the
 * dynamics leave alone (biases, ...). spec (doubles): [dt, servo_lag, wheel_lag, wheel_accel,
 * follow, have_A, rest command (alpha), wheel accelerations (n_w), setpoints at the step's
 * start (n_w), commands (n_w), jitter density (m^2 s), the mean kink's jitter std (m; 0: the
 * sharp kink), the filter's step (process_dt_s, s), RK4 substeps (ProcessModel.substeps)].
 * follow = 0: the wheels accelerate at the
 * given constant accelerations; 1: they lag (wheel_lag) behind setpoints ramping at wheel_accel
 * from the start setpoints towards the commands. */
typedef struct {
    double dt, servo_lag, wheel_lag, wheel_accel;
    int follow, have_A, substeps;
    double jitter, kink_sd, filter_dt;
    const double *rest_cmd, *wheel_acc, *sp0, *cmd;
} StepSpec;

static void step_spec(const double* s, const int64_t* d, StepSpec* p) {
    int64_t alpha = d[2], nw = d[3];
    p->dt = s[0];
    p->servo_lag = s[1];
    p->wheel_lag = s[2];
    p->wheel_accel = s[3];
    p->follow = s[4] != 0.0;
    p->have_A = s[5] != 0.0;
    p->rest_cmd = s + 6;
    p->wheel_acc = p->rest_cmd + alpha;
    p->sp0 = p->wheel_acc + nw;
    p->cmd = p->sp0 + nw;
    p->jitter = p->cmd[nw];
    p->kink_sd = p->cmd[nw + 1];
    p->filter_dt = p->cmd[nw + 2];
    p->substeps = p->cmd[nw + 3] > 1.0 ? (int)p->cmd[nw + 3] : 1;
}

static int64_t step_spec_size(const int64_t* d) {
    return 10 + d[2] + 3 * d[3];
}

/* E max(a - Z, 0) = a Phi(a) + phi(a), Z standard normal (gyrohost.estimator.kink). */
static double expected_positive_part(double a) {
    double Phi = 0.5 * erfc(-a / sqrt(2.0));
    return a * Phi + exp(-0.5 * a * a) / sqrt(2.0 * 3.14159265358979323846);
}

/* The mean kink (gyrohost.estimator.process_model.mean_force_rest_jacobian): the rest lengths
 * (alpha) at which the strings of the state z = [q, q_dot, omega_w, rest] pull with their
 * expected force under a rest-length jitter of std sd, rest + mu - sd g(mu / sd) with the
 * tension margin mu = s - rest + (c/k) s_dot, g = expected_positive_part; sd = 0: the rest
 * lengths. With Dm (alpha x D), their Jacobian: (1 - Phi) (u + (c/k) (S_dot - s_dot u) / s)
 * along the string's coordinates in q, (1 - Phi) (c/k) u in q_dot, Phi on its rest length. */
static void mean_pulling(const Consts* k, const int64_t* d, const double* z, double sd,
                         double* pulling, double* Dm) {
    int64_t m = d[0], beta = d[1], alpha = d[2], nw = d[3], K = beta + alpha;
    int64_t D = 6 * m + nw + alpha, r0 = 6 * m + nw;
    for (int64_t i = 0; Dm && i < alpha * D; i++) Dm[i] = 0.0;
    for (int64_t i = 0; i < alpha; i++) {
        int64_t j = beta + i;
        double rest = z[r0 + i], S[3], Sd[3], ss = 0.0, sv = 0.0;
        pulling[i] = rest;
        if (Dm) Dm[i * D + r0 + i] = 1.0;
        if (sd == 0.0) continue;
        for (int64_t a = 0; a < 3; a++) {
            S[a] = k->off[a * K + j];
            Sd[a] = 0.0;
            for (int64_t l = 0; l < m; l++) {
                S[a] += z[a * m + l] * k->EE_T[l * K + j];
                Sd[a] += z[3 * m + a * m + l] * k->EE_T[l * K + j];
            }
            ss += S[a] * S[a];
        }
        double s = sqrt(ss), ratio = k->c_s[i] / k->k_s[i], u[3];
        for (int64_t a = 0; a < 3; a++) {
            u[a] = S[a] / s;
            sv += u[a] * Sd[a];
        }
        double margin = s - rest + ratio * sv, x = margin / sd;
        pulling[i] = rest + margin - sd * expected_positive_part(x);
        if (!Dm) continue;
        double open = 0.5 * erfc(x / sqrt(2.0)); /* d pulling / d margin */
        for (int64_t a = 0; a < 3; a++) {
            double gq = open * (u[a] + ratio * (Sd[a] - sv * u[a]) / s), gd = open * ratio * u[a];
            for (int64_t l = 0; l < m; l++) {
                double e = k->EE_T[l * K + j];
                Dm[i * D + a * m + l] = gq * e;
                Dm[i * D + 3 * m + a * m + l] = gd * e;
            }
        }
        Dm[i * D + r0 + i] = 1.0 - open;
    }
}

/* dz/dt of z at time tau into the step but the accelerations (dz[3m:6m]): positions move with
 * the rates, the wheels follow their setpoints (or the given accelerations), the rest lengths
 * their lag. */
static void other_rates(const int64_t* d, const StepSpec* p, const double* z, double tau,
                        double* dz) {
    int64_t m = d[0], alpha = d[2], nw = d[3];
    const double *om = z + 6 * m, *rest = om + nw;
    for (int64_t i = 0; i < 3 * m; i++) dz[i] = z[3 * m + i];
    double reach = p->wheel_accel * tau;
    for (int64_t i = 0; i < nw; i++) {
        if (p->follow) {
            double step = p->cmd[i] - p->sp0[i];
            step = step > reach ? reach : (step < -reach ? -reach : step);
            dz[6 * m + i] = (p->sp0[i] + step - om[i]) / p->wheel_lag;
        } else {
            dz[6 * m + i] = p->wheel_acc[i];
        }
    }
    for (int64_t i = 0; i < alpha; i++)
        dz[6 * m + nw + i] = (p->rest_cmd[i] - rest[i]) / p->servo_lag;
}

/* dz/dt at time tau into the step; xm, um, out: the kernel's state, input and derivative
 * (work); w: the kernel's work. */
static int64_t filter_derivative(const Consts* k, const int64_t* d, const StepSpec* p,
                                 const double* z, double tau, double* dz, double* xm, double* um,
                                 double* out, double* w) {
    int64_t m = d[0], alpha = d[2], nw = d[3], ntq = d[4];
    const double* om = z + 6 * m;
    for (int64_t i = 0; i < 6 * m; i++) xm[i] = z[i];
    for (int64_t i = 0; i < nw; i++) xm[6 * m + i] = 0.0; /* wheel angles: no force sees them */
    for (int64_t t = 0; t < ntq; t++) {
        double s = 0.0;
        for (int64_t i = 0; i < nw; i++) s += k->tsel[t * nw + i] * om[i];
        xm[6 * m + nw + t] = s;
    }
    mean_pulling(k, d, z, p->kink_sd, um, NULL);
    for (int64_t i = 0; i < nw; i++) um[alpha + i] = om[i]; /* speed wheels read it from u */
    int64_t status = evaluate(k, d, xm, um, out, w);
    if (status) return status;
    for (int64_t i = 0; i < 3 * m; i++) dz[3 * m + i] = out[3 * m + i];
    other_rates(d, p, z, tau, dz);
    return 0;
}

/* BLAS's dgemm (column-major), handed over by use_blas() (scipy's cython_blas: the BLAS numpy
 * and scipy use); without it, plain loops. At the filter's sizes (30 to 40) the library's
 * products take a third of the loops' time (SSE2 only: the build targets any x86-64). */
typedef void (*dgemm_fn)(char*, char*, int*, int*, int*, double*, double*, int*, double*, int*,
                         double*, double*, int*);
static dgemm_fn blas_dgemm = NULL;

/* C = a op(A) op(B) + b C, row-major: op(A) r x k (A itself r x k, or k x r transposed,
 * trans_a; leading dimension lda), op(B) k x c (B k x c, or c x k transposed, trans_b), C r x c
 * (ldc). */
static void gemm2(int trans_a, int trans_b, int r, int c, int k, double a, const double* A, int lda,
                  const double* B, int ldb, double b, double* C, int ldc) {
    if (blas_dgemm) { /* column-major: C^T = op(B)^T op(A)^T */
        char tb = trans_b ? 'T' : 'N', ta = trans_a ? 'T' : 'N';
        blas_dgemm(&tb, &ta, &c, &r, &k, &a, (double*)B, &ldb, (double*)A, &lda, &b, C, &ldc);
        return;
    }
    for (int i = 0; i < r; i++) {
        double* row = C + (int64_t)i * ldc;
        for (int j = 0; j < c; j++) row[j] = b == 0.0 ? 0.0 : b * row[j];
        for (int l = 0; l < k; l++) {
            double f = a * (trans_a ? A[(int64_t)l * lda + i] : A[(int64_t)i * lda + l]);
            if (f == 0.0) continue;
            if (trans_b) {
                for (int j = 0; j < c; j++) row[j] += f * B[(int64_t)j * ldb + l];
            } else {
                const double* src = B + (int64_t)l * ldb;
                for (int j = 0; j < c; j++) row[j] += f * src[j];
            }
        }
    }
}

static void gemm(int trans_b, int r, int c, int k, double a, const double* A, int lda,
                 const double* B, int ldb, double b, double* C, int ldc) {
    gemm2(0, trans_b, r, c, k, a, A, lda, B, ldb, b, C, ldc);
}

/* Work entries mean_jacobian() needs (doubles). */
static int64_t mean_jacobian_work(const int64_t* d) {
    int64_t m = d[0], alpha = d[2], D = 6 * m + d[3] + alpha;
    return jacobian_work(d) + D + alpha * D + 3 * m * alpha;
}

/* jacobian() under the mean kink of jitter std sd (mean_pulling; sd = 0: jacobian() itself):
 * the accelerations at the pulling rest lengths and their Jacobian through them, the rest
 * lengths' columns J_r chained: J[:, rest] = 0, J += J_r Dm. */
static int64_t mean_jacobian(const Consts* k, const int64_t* d, double sd, const double* x,
                             double* acc, double* J, double* w) {
    if (sd == 0.0) return jacobian(k, d, x, acc, J, w);
    int64_t m = d[0], alpha = d[2], D = 6 * m + d[3] + alpha, r0 = D - alpha;
    double *z = w, *Dm = z + D, *Jr = Dm + alpha * D;
    for (int64_t i = 0; i < D; i++) z[i] = x[i];
    mean_pulling(k, d, x, sd, z + r0, Dm);
    int64_t status = jacobian(k, d, z, acc, J, Jr + 3 * m * alpha);
    if (status) return status;
    for (int64_t r = 0; r < 3 * m; r++) {
        for (int64_t i = 0; i < alpha; i++) {
            Jr[r * alpha + i] = J[r * D + r0 + i];
            J[r * D + r0 + i] = 0.0;
        }
    }
    gemm(0, (int)(3 * m), (int)D, (int)alpha, 1.0, Jr, (int)alpha, Dm, (int)D, 1.0, J, (int)D);
    return 0;
}

/* C = h A B + c0 I for the lean step's A (D x D): rows of q take B's q_dot rows, rows of
 * q_dot the accelerations' Jacobian Jq (3 m x D) times B, the wheels' and rest lengths' rows
 * their diagonal slopes; B is D x D. */
static void apply_A(const int64_t* d, const double* Jq, double h, double wslope, double rslope,
                    double c0, const double* B, double* C) {
    int64_t m = d[0], nw = d[3], D = 6 * m + nw + d[2];
    for (int64_t i = 0; i < 3 * m; i++)
        for (int64_t c = 0; c < D; c++) C[i * D + c] = h * B[(3 * m + i) * D + c];
    gemm(0, (int)(3 * m), (int)D, (int)D, h, Jq, (int)D, B, (int)D, 0.0, C + 3 * m * D, (int)D);
    for (int64_t i = 6 * m; i < D; i++) {
        double g = h * (i < 6 * m + nw ? wslope : rslope);
        for (int64_t c = 0; c < D; c++) C[i * D + c] = g * B[i * D + c];
    }
    for (int64_t i = 0; i < D; i++) C[i * D + i] += c0;
}

/* Po = F P F^T for F (D x D) on the leading D entries of the n-entry state, the identity
 * beyond: FP = F P[:D, :] (D x n), then FP F^T. */
static void propagate(int64_t D, int64_t n, const double* F, const double* P, double* FP,
                      double* Po) {
    int iD = (int)D, in = (int)n;
    gemm(0, iD, in, iD, 1.0, F, iD, P, in, 0.0, FP, in);
    gemm(1, iD, iD, iD, 1.0, FP, in, F, iD, 0.0, Po, in);
    for (int64_t i = 0; i < D; i++)
        for (int64_t c = D; c < n; c++) Po[i * n + c] = Po[c * n + i] = FP[i * n + c];
    for (int64_t i = D; i < n; i++)
        for (int64_t c = D; c < n; c++) Po[i * n + c] = P[i * n + c];
}

/* Work entries lean_step() needs (doubles). */
static int64_t lean_work(const int64_t* d, int64_t n) {
    int64_t m = d[0], beta = d[1], alpha = d[2], nw = d[3], ntq = d[4], cu = d[5];
    int64_t K = beta + alpha, D = 6 * m + nw + alpha, nb = beta + 3 * cu;
    int64_t ev = 9 * K + 6 * m + 3 * beta + nw + nb + nb * nb, jw = mean_jacobian_work(d);
    int64_t sz = 6 * m + nw + ntq;
    return 4 * D + 2 * sz + alpha + nw + 3 * m + 3 * m * D + 4 * D * D + D * n + 6 * K + 2 * D +
           3 * m + 9 * m * alpha + alpha + (ev > jw ? ev : jw);
}

/* Mean square of max(a - Z, 0) - max(a, 0), Z standard normal (gyrohost.estimator.kink). */
static double kink_weight(double a) {
    double Phi = 0.5 * erfc(-a / sqrt(2.0)),
           phi = exp(-0.5 * a * a) / sqrt(2.0 * 3.14159265358979323846);
    return a <= 0.0 ? (a * a + 1.0) * Phi + a * phi : Phi - a * phi + a * a * (1.0 - Phi);
}

#define KINK_REACH 7.0 /* gyrohost.estimator.process_noise.KINK_REACH */
#define RK4_JUMP_VARIANCE (1.0 / 36.0) /* gyrohost.estimator.process_noise.RK4_JUMP_VARIANCE */

/* Var f - Cov(f, Z)^2 of f = (a + Z + j) 1[a + Z > 0], Z standard normal, j >= 0 the force's
 * jump: what no line in Z captures (gyrohost.estimator.kink.unexplained_variance). */
static double unexplained_variance(double a, double j) {
    double Phi = 0.5 * erfc(-a / sqrt(2.0)),
           phi = exp(-0.5 * a * a) / sqrt(2.0 * 3.14159265358979323846), b = a + j;
    return b * b * Phi * (1.0 - Phi) + 2.0 * b * phi * (1.0 - Phi) + Phi - a * phi - phi * phi -
           Phi * Phi - 2.0 * j * Phi * phi - j * j * phi * phi;
}

/* g P g^T over the dynamic block of P (n x n) for g (D) nonzero only at q, q_dot (6 m) and
 * the rest length r: the variance of string i's tension margin. */
static double margin_variance(const double* g, const double* P, int64_t n, int64_t m, int64_t r) {
    double s = 0.0;
    for (int64_t a = 0; a < 6 * m; a++) {
        double t = g[r] * P[a * n + r];
        for (int64_t b = 0; b < 6 * m; b++) t += P[a * n + b] * g[b];
        s += g[a] * t;
    }
    double t = g[r] * P[r * n + r];
    for (int64_t b = 0; b < 6 * m; b++) t += P[r * n + b] * g[b];
    return s + g[r] * t;
}

/* Po[:6m, :6m] += sum_i var_i G_i G_i^T, the force errors at the strings' kinks
 * (gyrohost.estimator.process_noise.kink_noise): G_i = dt/2 (b_i + F b_i), b_i = (0, d acc /
 * d rest_i) with string i held taut; var_i = (q / dt) kink_weight(mu_i / sqrt(q / dt)) for the
 * rest-length jitter of density q, plus sigma_i^2 unexplained_variance(mu_i / sigma_i, J_i /
 * sigma_i) x filter_dt / dt for the linearisation (a filter step's error, spread over a split
 * step's parts), sigma_i^2 = g_i P g_i^T the variance of the tension margin mu_i (a length) at
 * x, J_i the force's jump as a length ((c/k) s_dot of a lengthening string), plus J_i^2 / 36
 * where the string goes taut within the step (J_i / substeps: its substep's stages). Jt: 3 m x D
 * work. */
static int64_t kink_noise(const Consts* k, const int64_t* d, const StepSpec* p, int64_t n,
                          const double* x, const double* P, const double* F, double* Po,
                          double* Jt, double* v, double* w) {
    int64_t m = d[0], beta = d[1], alpha = d[2], nw = d[3], K = beta + alpha;
    int64_t D = 6 * m + nw + alpha, r0 = 6 * m + nw;
    double *pos = v, *vel = pos + 3 * K, *z = vel + 3 * K, *acc = z + D, *b = acc + 3 * m;
    double *G = b + 3 * m * alpha, *wt = G + 6 * m * alpha, *g = wt + alpha, dt = p->dt;
    double q = p->jitter;
    member_vectors(k, d, x, x + 3 * m, pos, vel);
    for (int64_t i = 0; i < D; i++) z[i] = x[i];
    for (int64_t i = 0; i < alpha; i++) {
        int64_t j = beta + i;
        double S[3] = {pos[j], pos[K + j], pos[2 * K + j]};
        double Sd[3] = {vel[j], vel[K + j], vel[2 * K + j]};
        double s = sqrt(S[0] * S[0] + S[1] * S[1] + S[2] * S[2]);
        double sdot = (S[0] * Sd[0] + S[1] * Sd[1] + S[2] * Sd[2]) / s;
        double ratio = k->c_s[i] / k->k_s[i];
        double stretch = s - x[r0 + i], damped = stretch + ratio * sdot;
        int on_damped = damped < stretch;
        double margin = on_damped ? damped : stretch;
        /* any taut point gives the column: the force is affine in the rest length there */
        z[r0 + i] = x[r0 + i] - (margin < 0.0 ? -margin : 0.0) - 1e-3;
        /* d margin / d (q, q_dot, rest_i) on the side of the min that holds */
        for (int64_t c = 0; c < D; c++) g[c] = 0.0;
        for (int64_t r = 0; r < 3; r++) {
            double u = S[r] / s, dq = u + (on_damped ? ratio * (Sd[r] - sdot * u) / s : 0.0);
            double dqd = on_damped ? ratio * u : 0.0;
            for (int64_t c = 0; c < m; c++) {
                g[r * m + c] = dq * k->EE_T[c * K + j];
                g[3 * m + r * m + c] = dqd * k->EE_T[c * K + j];
            }
        }
        g[r0 + i] = -1.0;
        double sigma2 = margin_variance(g, P, n, m, r0 + i);
        /* beyond KINK_REACH of its standard deviations the force is a line to round-off */
        int near = sigma2 > 0.0 && fabs(margin) < KINK_REACH * sqrt(sigma2);
        /* a lengthening string pulls with its damping as soon as it is taut: a jump */
        double sigma = sqrt(sigma2), jump = on_damped ? 0.0 : ratio * sdot;
        wt[i] = near ? sigma2 * unexplained_variance(margin / sigma, jump / sigma) *
                           p->filter_dt / dt
                     : 0.0;
        /* taut within the step: its substep's RK4 stages place its jump to within
         * RK4_JUMP_VARIANCE of the substep */
        if (margin <= 0.0 && margin + sdot * dt > 0.0 && jump > 0.0) {
            double share = jump / p->substeps;
            wt[i] += RK4_JUMP_VARIANCE * share * share;
        }
        if (q > 0.0) {
            double a = margin / sqrt(q / dt), mean = expected_positive_part(a) - (a > 0.0 ? a : 0.0);
            /* under the mean kink the prediction carries the mean force already */
            wt[i] += (q / dt) * (kink_weight(a) - (p->kink_sd > 0.0 ? mean * mean : 0.0));
        }
    }
    int any = 0;
    for (int64_t i = 0; i < alpha; i++) any |= wt[i] != 0.0;
    if (!any) return 0; /* every string a line to round-off: no Jacobian needed */
    int64_t status = jacobian_columns(k, d, z, acc, Jt, w, r0, D); /* the rest lengths' */
    if (status) return status;
    for (int64_t r = 0; r < 3 * m; r++)
        for (int64_t i = 0; i < alpha; i++) b[r * alpha + i] = Jt[r * D + r0 + i];
    /* G = dt/2 (F[:6m, q_dot] b + (0; b)) */
    gemm(0, (int)(6 * m), (int)alpha, (int)(3 * m), 0.5 * dt, F + 3 * m, (int)D, b, (int)alpha, 0.0,
         G, (int)alpha);
    for (int64_t r = 0; r < 3 * m * alpha; r++) G[3 * m * alpha + r] += 0.5 * dt * b[r];
    for (int64_t r = 0; r < 6 * m; r++) {
        for (int64_t c = 0; c < 6 * m; c++) {
            double s = 0.0;
            for (int64_t i = 0; i < alpha; i++) s += G[r * alpha + i] * wt[i] * G[c * alpha + i];
            Po[r * n + c] += s;
        }
    }
    return 0;
}

/* A (D x D) of the lean model from the accelerations' Jacobian Jq (3 m x D): rows of q take
 * the identity on q_dot, the wheels' and rest lengths' rows their diagonal slopes. */
static void dense_A(const int64_t* d, const double* Jq, double wslope, double rslope, double* A) {
    int64_t m = d[0], nw = d[3], D = 6 * m + nw + d[2];
    for (int64_t i = 0; i < D * D; i++) A[i] = 0.0;
    for (int64_t i = 0; i < 3 * m; i++) A[i * D + 3 * m + i] = 1.0;
    for (int64_t i = 0; i < 3 * m * D; i++) A[3 * m * D + i] = Jq[i];
    for (int64_t i = 6 * m; i < D; i++) A[i * D + i] = i < 6 * m + nw ? wslope : rslope;
}

/* One RK4 stage at z, tau into the step: its slope dz (D) and the accelerations' Jacobian Jq
 * (3 m x D) in one evaluation of the closed form (mean_jacobian). */
static int64_t stage(const Consts* k, const int64_t* d, const StepSpec* p, const double* z,
                     double tau, double* dz, double* Jq, double* acc, double* w) {
    int64_t m = d[0];
    int64_t status = mean_jacobian(k, d, p->kink_sd, z, acc, Jq, w);
    if (status) return status;
    for (int64_t i = 0; i < 3 * m; i++) dz[3 * m + i] = acc[i];
    other_rates(d, p, z, tau, dz);
    return 0;
}

/* One lean step (gyrohost.estimator.process_model._lean): p->substeps classic RK4 substeps of
 * h = dt / substeps for z, and F (D x D, returned for the process noise) their Jacobian by the
 * chain rule through the stages: per substep D2 = A2 (I + h/2 A1), D3 = A3 (I + h/2 D2), D4 =
 * A4 (I + h D3), F <- (I + h/6 (A1 + 2 D2 + 2 D3 + D4)) F, A_i at the stage's state (the first
 * stage's A given in Ain, D x D, when have_A; a later substep's first the substep before's last,
 * within h^2 of its start); Po = F P F^T (F the identity beyond D; n x n).
 * Status as evaluate(). */
static int64_t lean_step(const Consts* k, const int64_t* d, const StepSpec* p, int64_t n,
                         const double* x, const double* P, const double* Ain, double* xo,
                         double* Po, double* F, double* w) {
    int64_t m = d[0], nw = d[3], ntq = d[4], D = 6 * m + nw + d[2], sz = 6 * m + nw + ntq;
    double *ks = w, *kst = ks + D, *zs = kst + D, *xc = zs + D;
    double *xm = xc + D, *out = xm + sz, *um = out + sz, *acc = um + d[2] + nw;
    double *Jq = acc + 3 * m, *T = Jq + 3 * m * D, *Dk = T + D * D, *S = Dk + D * D;
    double *Ft = S + D * D, *FP = Ft + D * D;
    double *kw = FP + D * n + 6 * (d[1] + d[2]) + 2 * D + 3 * m + 9 * m * d[2] + d[2];
    double wslope = p->follow ? -1.0 / p->wheel_lag : 0.0, rslope = -1.0 / p->servo_lag;
    int64_t steps = p->substeps, status = 0;
    double h = p->dt / (double)steps;
    static const double frac[3] = {0.5, 0.5, 1.0}, weight[3] = {2.0, 2.0, 1.0};
    if (p->have_A && nw) wslope = Ain[(6 * m) * D + 6 * m];
    for (int64_t i = 0; i < D; i++) xc[i] = x[i];
    for (int64_t j = 0; j < steps; j++) {
        double t0 = j * h;
        if (j == 0 && p->have_A) {
            for (int64_t i = 0; i < 3 * m * D; i++) Jq[i] = Ain[3 * m * D + i];
            status = filter_derivative(k, d, p, xc, t0, kst, xm, um, out, kw);
        } else if (j > 0) { /* Jq: the substep before's last stage's, at xc + h k3 */
            status = filter_derivative(k, d, p, xc, t0, kst, xm, um, out, kw);
        } else {
            status = stage(k, d, p, xc, t0, kst, Jq, acc, kw);
        }
        if (status) return status;
        dense_A(d, Jq, wslope, rslope, S); /* S = A1 */
        for (int64_t i = 0; i < D * D; i++) T[i] = 0.5 * h * S[i];
        for (int64_t i = 0; i < D; i++) {
            T[i * D + i] += 1.0;
            ks[i] = kst[i];
        }
        for (int s2 = 0; s2 < 3; s2++) { /* stages 2 to 4 */
            for (int64_t i = 0; i < D; i++) zs[i] = xc[i] + frac[s2] * h * kst[i];
            status = stage(k, d, p, zs, t0 + frac[s2] * h, kst, Jq, acc, kw);
            if (status) return status;
            apply_A(d, Jq, 1.0, wslope, rslope, 0.0, T, Dk); /* D_i = A_i T */
            double next = s2 == 0 ? 0.5 * h : h;             /* T = I + (h/2 or h) D_i */
            for (int64_t i = 0; i < D * D; i++) {
                S[i] += weight[s2] * Dk[i];
                T[i] = next * Dk[i];
            }
            for (int64_t i = 0; i < D; i++) {
                T[i * D + i] += 1.0;
                ks[i] += weight[s2] * kst[i];
            }
        }
        for (int64_t i = 0; i < D; i++) xc[i] += (h / 6.0) * ks[i];
        double* Fs = j == 0 ? F : Ft; /* the substep's I + h/6 S */
        for (int64_t i = 0; i < D * D; i++) Fs[i] = (h / 6.0) * S[i];
        for (int64_t i = 0; i < D; i++) Fs[i * D + i] += 1.0;
        if (j > 0) {
            gemm(0, (int)D, (int)D, (int)D, 1.0, Ft, (int)D, F, (int)D, 0.0, Dk, (int)D);
            for (int64_t i = 0; i < D * D; i++) F[i] = Dk[i];
        }
    }
    for (int64_t i = 0; i < D; i++) xo[i] = xc[i];
    for (int64_t i = D; i < n; i++) xo[i] = x[i];
    propagate(D, n, F, P, FP, Po);
    return kink_noise(k, d, p, n, x, P, F, Po, Jq, FP + D * n, kw);
}

/* ---- The filter's constraint manifold (gyrohost.estimator.manifold) ----
 * Bars B = B0 + q E^T (3 x beta) and their rates B_dot = q_dot E^T of a filter state whose
 * first 6 m entries are q, q_dot (3 x m each, row by row); E beta x m, l2 the bars' squared
 * lengths. */
typedef struct {
    int64_t m, beta, n;
    const double *E, *B0, *l2;
} Bars;

static void bar_vectors(const Bars* b, const double* x, double* B, double* Bd) {
    int64_t m = b->m, beta = b->beta;
    for (int64_t a = 0; a < 3; a++) {
        for (int64_t i = 0; i < beta; i++) {
            double p = b->B0[a * beta + i], v = 0.0;
            for (int64_t l = 0; l < m; l++) {
                p += x[a * m + l] * b->E[i * m + l];
                v += x[3 * m + a * m + l] * b->E[i * m + l];
            }
            B[a * beta + i] = p;
            Bd[a * beta + i] = v;
        }
    }
}

/* rows i of D (leading dimension ld, from column c0): d(b_i . V_i)/dq = s V[:, i] x E[i, :]
 * (the bar's vector moves with the coordinates its row of E names). */
static void bar_rows(const Bars* b, const double* V, double s, double* D, int64_t ld, int64_t c0) {
    int64_t m = b->m, beta = b->beta;
    for (int64_t i = 0; i < beta; i++)
        for (int64_t a = 0; a < 3; a++)
            for (int64_t l = 0; l < m; l++)
                D[i * ld + c0 + a * m + l] = s * V[a * beta + i] * b->E[i * m + l];
}

/* x[0:nc] -= G^T (G G^T)^-1 r, the minimum-norm step that zeroes the linearised residual r (k
 * rows of G, k x nc; gram k x k work). Status as cholesky_factor. */
static int64_t min_norm_step(int64_t k, int64_t nc, const double* G, double* r, double* x,
                             double* gram) {
    gemm(1, (int)k, (int)k, (int)nc, 1.0, G, (int)nc, G, (int)nc, 0.0, gram, (int)k);
    int64_t status = cholesky_solve(gram, r, k);
    if (status) return status;
    for (int64_t i = 0; i < k; i++)
        for (int64_t c = 0; c < nc; c++) x[c] -= G[i * nc + c] * r[i];
    return 0;
}

/* The state x moved onto the constraints: Gauss-Newton steps on q until every |b|^2 - l^2 is
 * within rtol of l^2 (at most iterations), then q_dot. Work: manifold_work(). */
static int64_t project_bars(const Bars* b, double* x, double rtol, int64_t iterations, double* w) {
    int64_t m = b->m, beta = b->beta;
    double *B = w, *Bd = B + 3 * beta, *g = Bd + 3 * beta, *G = g + beta, *gram = G + 3 * m * beta;
    int64_t status;
    for (int64_t it = 0; it < iterations; it++) {
        bar_vectors(b, x, B, Bd);
        double worst = 0.0;
        for (int64_t i = 0; i < beta; i++) {
            double bb = B[i] * B[i] + B[beta + i] * B[beta + i] + B[2 * beta + i] * B[2 * beta + i];
            g[i] = bb - b->l2[i];
            double rel = fabs(g[i]) / b->l2[i];
            if (rel > worst || isnan(rel)) worst = rel;
        }
        if (worst <= rtol) break;
        bar_rows(b, B, 2.0, G, 3 * m, 0);
        status = min_norm_step(beta, 3 * m, G, g, x, gram);
        if (status) return status;
    }
    bar_vectors(b, x, B, Bd);
    for (int64_t i = 0; i < beta; i++) {
        double s = 0.0;
        for (int64_t a = 0; a < 3; a++) s += B[a * beta + i] * Bd[a * beta + i];
        g[i] = s;
    }
    bar_rows(b, B, 1.0, G, 3 * m, 0);
    return min_norm_step(beta, 3 * m, G, g, x + 3 * m, gram);
}

static int64_t manifold_work(int64_t m, int64_t beta, int64_t n) {
    int64_t k = 2 * beta;
    return 8 * beta + 3 * m * beta + k * k + 4 * k * n + 2 * n * n + k;
}

/* x projected (project_bars) and Po = Pi P Pi^T symmetrised, Pi = I - G^T (G G^T)^-1 G the
 * projector onto the constraints' tangent space at x (G: 2 beta x n, positions' then
 * velocities' constraints): with Y = (G G^T)^-1 G, Pi P = P - G^T (Y P) and Pi P Pi^T =
 * Pi P - (Pi P Y^T) G. */
static int64_t condition_bars(const Bars* b, double* x, const double* P, double* Po, double rtol,
                              int64_t iterations, double* w) {
    int64_t m = b->m, beta = b->beta, n = b->n, k = 2 * beta;
    int64_t status = project_bars(b, x, rtol, iterations, w);
    if (status) return status;
    double *B = w, *Bd = B + 3 * beta, *gram = Bd + 3 * beta, *G = gram + k * k, *Y = G + k * n;
    double *YP = Y + k * n, *PiP = YP + k * n, *T = PiP + n * n, *col = T + n * n;
    bar_vectors(b, x, B, Bd);
    for (int64_t i = 0; i < k * n; i++) G[i] = 0.0;
    bar_rows(b, B, 2.0, G, n, 0);
    bar_rows(b, Bd, 1.0, G + beta * n, n, 0);
    bar_rows(b, B, 1.0, G + beta * n, n, 3 * m);
    gemm(1, (int)k, (int)k, (int)n, 1.0, G, (int)n, G, (int)n, 0.0, gram, (int)k);
    status = cholesky_factor(gram, k);
    if (status) return status;
    for (int64_t c = 0; c < n; c++) {
        for (int64_t i = 0; i < k; i++) col[i] = G[i * n + c];
        cholesky_subst(gram, col, k);
        for (int64_t i = 0; i < k; i++) Y[i * n + c] = col[i];
    }
    int in = (int)n, ik = (int)k;
    gemm(0, ik, in, in, 1.0, Y, in, P, in, 0.0, YP, in);
    for (int64_t i = 0; i < n * n; i++) PiP[i] = P[i];
    gemm2(1, 0, in, in, ik, -1.0, G, in, YP, in, 1.0, PiP, in);
    gemm(1, in, ik, in, 1.0, PiP, in, Y, in, 0.0, T, ik);
    for (int64_t i = 0; i < n * n; i++) Po[i] = PiP[i];
    gemm(0, in, in, ik, -1.0, T, ik, G, in, 1.0, Po, in);
    for (int64_t i = 0; i < n; i++) {
        for (int64_t j = 0; j < i; j++) {
            double s = 0.5 * (Po[i * n + j] + Po[j * n + i]);
            Po[i * n + j] = Po[j * n + i] = s;
        }
    }
    return 0;
}

/* ---- The IMU's prediction (gyrohost.estimator.imu_prediction, closed form) ----
 * The sensor frame of three nodes a, b, c (x along a -> b, z along x cross (c - a)) and its
 * angular rate, differentiated in forward mode: a dual number carries one directional
 * derivative. */
typedef struct {
    double v, d;
} Dual;

static Dual dmul(Dual a, Dual b) {
    Dual r = {a.v * b.v, a.d * b.v + a.v * b.d};
    return r;
}
static Dual dsub(Dual a, Dual b) {
    Dual r = {a.v - b.v, a.d - b.d};
    return r;
}
static Dual ddiv(Dual a, Dual b) {
    Dual r = {a.v / b.v, (a.d * b.v - a.v * b.d) / (b.v * b.v)};
    return r;
}
static Dual ddot(const Dual* a, const Dual* b) {
    Dual r = dmul(a[0], b[0]), t;
    for (int i = 1; i < 3; i++) {
        t = dmul(a[i], b[i]);
        r.v += t.v;
        r.d += t.d;
    }
    return r;
}
static void dcross(const Dual* a, const Dual* b, Dual* c) {
    for (int i = 0; i < 3; i++) {
        int j = (i + 1) % 3, k = (i + 2) % 3;
        c[i] = dsub(dmul(a[j], b[k]), dmul(a[k], b[j]));
    }
}
static Dual dsqrt(Dual a) {
    double r = sqrt(a.v);
    Dual o = {r, a.d / (2.0 * r)};
    return o;
}
/* u = v / len and u_dot = (v_dot - u (u . v_dot)) / len: a unit vector and its rate. */
static void unit_and_rate(const Dual* v, const Dual* v_dot, Dual* u, Dual* u_dot) {
    Dual len = dsqrt(ddot(v, v));
    for (int i = 0; i < 3; i++) u[i] = ddiv(v[i], len);
    Dual p = ddot(u, v_dot);
    for (int i = 0; i < 3; i++) u_dot[i] = ddiv(dsub(v_dot[i], dmul(u[i], p)), len);
}

/* in = [d1, d2, d1_dot, d2_dot] (d1 = N_b - N_a, d2 = N_c - N_a): R_ws (3 x 3, row-major) =
 * [ex ey ez] R_bs and omega_s = omega_b R_bs, omega_b = (-ey . ez_dot, ex . ez_dot, ey . ex_dot).
 */
static void sensor_frame(const Dual* in, const double* Rbs, Dual* R, Dual* om) {
    Dual ex[3], ex_dot[3], c[3], c_dot[3], t[3], ez[3], ez_dot[3], ey[3], ob[3], zero = {0.0, 0.0};
    unit_and_rate(in, in + 6, ex, ex_dot);
    dcross(in, in + 3, c);
    dcross(in + 6, in + 3, c_dot);
    dcross(in, in + 9, t);
    for (int i = 0; i < 3; i++) {
        c_dot[i].v += t[i].v;
        c_dot[i].d += t[i].d;
    }
    unit_and_rate(c, c_dot, ez, ez_dot);
    dcross(ez, ex, ey);
    ob[0] = dsub(zero, ddot(ey, ez_dot));
    ob[1] = ddot(ex, ez_dot);
    ob[2] = ddot(ey, ex_dot);
    for (int r = 0; r < 3; r++) {
        const Dual col[3] = {ex[r], ey[r], ez[r]};
        for (int j = 0; j < 3; j++) {
            Dual s = zero;
            for (int i = 0; i < 3; i++) {
                s.v += col[i].v * Rbs[i * 3 + j];
                s.d += col[i].d * Rbs[i * 3 + j];
            }
            R[r * 3 + j] = s;
        }
    }
    for (int j = 0; j < 3; j++) {
        Dual s = zero;
        for (int i = 0; i < 3; i++) {
            s.v += ob[i].v * Rbs[i * 3 + j];
            s.d += ob[i].d * Rbs[i * 3 + j];
        }
        om[j] = s;
    }
}

/* spec (doubles): [servo_lag, wheel slope, rest command (alpha), wheel accelerations (n_w),
 * gravity (3), R_bs (9), node rows of U for a, b, c (3 x m), N_fix at a, b, c (3 x 3: node,
 * then axis), the mean kink's jitter std (m; 0: the sharp kink)]. */
static int64_t imu_spec_size(const int64_t* d) {
    return 2 + d[2] + d[3] + 3 + 9 + 3 * d[0] + 9 + 1;
}

static int64_t imu_work(const int64_t* d) {
    return mean_jacobian_work(d);
}

/* The IMU's values and Jacobians at the filter state x (its first D = 6 m + n_w + alpha
 * entries): f = dx/dt (D), A = df/dx (D x D), R (9) and dR (9 x D), omega (3) and its
 * Jacobian (3 x D), the specific force (3) and its Jacobian (3 x D). Status as evaluate(). */
static int64_t imu_predict(const Consts* k, const int64_t* d, const double* spec, const double* x,
                           double* f, double* A, double* R, double* dR, double* om, double* dom,
                           double* fs, double* dfs, double* w) {
    int64_t m = d[0], alpha = d[2], nw = d[3], D = 6 * m + nw + alpha;
    const double *rest_cmd = spec + 2, *wacc = rest_cmd + alpha, *g = wacc + nw, *Rbs = g + 3;
    const double *ua = Rbs + 9, *ub = ua + m, *uc = ub + m, *Nf = uc + m;
    double acc[3 * 100], *J = A + 3 * m * D; /* the q_dot rows of A */
    int64_t status = mean_jacobian(k, d, spec[imu_spec_size(d) - 1], x, acc, J, w);
    if (status) return status;
    for (int64_t i = 0; i < 3 * m * D; i++) A[i] = 0.0;
    for (int64_t i = 6 * m * D; i < D * D; i++) A[i] = 0.0;
    for (int64_t i = 0; i < 3 * m; i++) A[i * D + 3 * m + i] = 1.0;
    for (int64_t i = 6 * m; i < 6 * m + nw; i++) A[i * D + i] = spec[1];
    for (int64_t i = 6 * m + nw; i < D; i++) A[i * D + i] = -1.0 / spec[0];
    for (int64_t i = 0; i < 3 * m; i++) {
        f[i] = x[3 * m + i];
        f[3 * m + i] = acc[i];
    }
    for (int64_t i = 0; i < nw; i++) f[6 * m + i] = wacc[i];
    for (int64_t i = 0; i < alpha; i++)
        f[6 * m + nw + i] = (rest_cmd[i] - x[6 * m + nw + i]) / spec[0];
    /* the frame's inputs and their derivatives, one direction at a time */
    Dual in[12], Rd[9], omd[3];
    double e1[100], e2[100], v[12], dRin[12][9], domin[12][3];
    for (int64_t l = 0; l < m; l++) {
        e1[l] = ub[l] - ua[l];
        e2[l] = uc[l] - ua[l];
    }
    for (int r = 0; r < 3; r++) {
        double pa = Nf[r], pb = Nf[3 + r], pc = Nf[6 + r], va = 0.0, vb = 0.0, vc = 0.0;
        for (int64_t l = 0; l < m; l++) {
            pa += x[r * m + l] * ua[l];
            pb += x[r * m + l] * ub[l];
            pc += x[r * m + l] * uc[l];
            va += x[3 * m + r * m + l] * ua[l];
            vb += x[3 * m + r * m + l] * ub[l];
            vc += x[3 * m + r * m + l] * uc[l];
        }
        v[r] = pb - pa;
        v[3 + r] = pc - pa;
        v[6 + r] = vb - va;
        v[9 + r] = vc - va;
    }
    for (int dir = 0; dir < 12; dir++) {
        for (int i = 0; i < 12; i++) {
            in[i].v = v[i];
            in[i].d = i == dir;
        }
        sensor_frame(in, Rbs, Rd, omd);
        for (int i = 0; i < 9; i++) dRin[dir][i] = Rd[i].d;
        for (int i = 0; i < 3; i++) domin[dir][i] = omd[i].d;
    }
    for (int i = 0; i < 9; i++) R[i] = Rd[i].v;
    for (int i = 0; i < 3; i++) om[i] = omd[i].v;
    for (int64_t i = 0; i < 9 * D; i++) dR[i] = 0.0;
    for (int64_t i = 0; i < 3 * D; i++) dom[i] = 0.0;
    /* q_{r,l} moves d1[r] by e1[l] and d2[r] by e2[l]; q_dot_{r,l} the rates alike */
    for (int r = 0; r < 3; r++) {
        for (int64_t l = 0; l < m; l++) {
            int64_t cq = r * m + l, cv = 3 * m + r * m + l;
            for (int i = 0; i < 9; i++)
                dR[i * D + cq] = e1[l] * dRin[r][i] + e2[l] * dRin[3 + r][i];
            for (int i = 0; i < 3; i++) {
                dom[i * D + cq] = e1[l] * domin[r][i] + e2[l] * domin[3 + r][i];
                dom[i * D + cv] = e1[l] * domin[6 + r][i] + e2[l] * domin[9 + r][i];
            }
        }
    }
    /* a = (N_ddot_a + N_ddot_b) / 2 - g, f_s = R^T a, df = R^T da + dR^T a */
    double a[3];
    for (int r = 0; r < 3; r++) {
        double s = 0.0;
        for (int64_t l = 0; l < m; l++) s += acc[r * m + l] * 0.5 * (ua[l] + ub[l]);
        a[r] = s - g[r];
    }
    for (int i = 0; i < 3; i++) {
        fs[i] = R[i] * a[0] + R[3 + i] * a[1] + R[6 + i] * a[2];
        for (int64_t c = 0; c < D; c++) {
            double s = 0.0;
            for (int r = 0; r < 3; r++) {
                double da = 0.0;
                for (int64_t l = 0; l < m; l++)
                    da += J[(r * m + l) * D + c] * 0.5 * (ua[l] + ub[l]);
                s += R[r * 3 + i] * da + dR[(r * 3 + i) * D + c] * a[r];
            }
            dfs[i * D + c] = s;
        }
    }
    return 0;
}

/* ---- The IMU's three measurements (gyrohost.estimator.fuse_imu_*, fast path) ---- */

/* Rotation vector (3) of the rotation R (3 x 3, row-major), as geometry.rotation_vector. */
static void rotation_log(const double* R, double* v) {
    double tr = R[0] + R[4] + R[8], q[4];
    int i = 0;
    for (int j = 1; j < 3; j++)
        if (R[j * 4] > R[i * 4]) i = j;
    if (tr >= R[i * 4]) {
        q[0] = R[7] - R[5];
        q[1] = R[2] - R[6];
        q[2] = R[3] - R[1];
        q[3] = 1.0 + tr;
    } else {
        int j = (i + 1) % 3, k = (i + 2) % 3;
        q[i] = 1.0 - tr + 2.0 * R[i * 4];
        q[j] = R[j * 3 + i] + R[i * 3 + j];
        q[k] = R[k * 3 + i] + R[i * 3 + k];
        q[3] = R[k * 3 + j] - R[j * 3 + k];
    }
    double norm = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    double sign = q[3] < 0.0 ? -1.0 : 1.0;
    for (int j = 0; j < 4; j++) q[j] *= sign / norm;
    double sine = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2]);
    double angle = 2.0 * atan2(sine, q[3]), scale;
    if (angle <= 1e-3)
        scale = 2.0 + angle * angle / 12.0 + 7.0 * angle * angle * angle * angle / 2880.0;
    else
        scale = angle / sin(angle / 2.0);
    for (int j = 0; j < 3; j++) v[j] = scale * q[j];
}

/* One IMU measurement's rows (3) of H (n columns: the Jacobian J (3 x k) at the columns cols,
 * the identity at bias, if >= 0), its prediction taken back by lag (hx = h - lag J x_dot), and
 * its noise std^2 I + tau^2 h_dot h_dot^T into the 3 x 3 block of Rm (ld 9) at (o, o). */
static void imu_rows(int64_t n, int64_t k, const int64_t* cols, const double* J, const double* h,
                     const double* xdot, double lag, double tau, double std, int64_t bias,
                     const double* x, int64_t o, double* H, double* hx, double* Rm) {
    double hd[3];
    for (int r = 0; r < 3; r++) {
        double* row = H + (o + r) * n;
        for (int64_t c = 0; c < n; c++) row[c] = 0.0;
        double s = 0.0;
        for (int64_t c = 0; c < k; c++) {
            row[cols[c]] = J[r * k + c];
            s += J[r * k + c] * xdot[c];
        }
        hd[r] = s;
        if (bias >= 0) row[bias + r] = 1.0;
        hx[o + r] = h[r] - lag * s + (bias >= 0 ? x[bias + r] : 0.0);
    }
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            Rm[(o + r) * 9 + o + c] = (r == c ? std * std : 0.0) + tau * tau * hd[r] * hd[c];
}

/* The rate (rows 0-2), specific force (3-5) and attitude (6-8) measurements of an IMU sample
 * z = (omega, accel, Z-Y-X angles) from the prediction (R, dR 9 x k, om, dom, f, df, x_dot
 * over the state columns cols): H (9 x n), hx, z_out (the angle's as the rotation vector
 * log(R_m R^T) + lag w, its hx 0) and R (9 x 9; zero off the blocks). spec: [lag, tau, std of
 * rate, accel, angle, floor, bias column, accelerometer bias column or -1]. */
static void imu_measurements(int64_t n, int64_t k, const int64_t* cols, const double* spec,
                             const double* const* pred, const double* x, const double* z, double* H,
                             double* hx, double* zo, double* Rm) {
    const double *R = pred[0], *dR = pred[1], *om = pred[2], *dom = pred[3], *f = pred[4];
    const double *df = pred[5], *xdot = pred[6];
    double lag = spec[0], tau = spec[1], sa = spec[4], floor_ = spec[5];
    for (int i = 0; i < 81; i++) Rm[i] = 0.0;
    for (int i = 0; i < 6; i++) zo[i] = z[i];
    imu_rows(n, k, cols, dom, om, xdot, lag, tau, spec[2], (int64_t)spec[6], x, 0, H, hx, Rm);
    imu_rows(n, k, cols, df, f, xdot, lag, tau, spec[3], (int64_t)spec[7], x, 3, H, hx, Rm);
    /* attitude: J = vee(dR_j R^T) per column, w = J x_dot */
    double J[3 * 256], w[3] = {0.0, 0.0, 0.0};
    for (int64_t c = 0; c < k; c++) {
        double M[9];
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) {
                double s = 0.0;
                for (int j = 0; j < 3; j++) s += dR[(a * 3 + j) * k + c] * R[b * 3 + j];
                M[a * 3 + b] = s;
            }
        J[c] = 0.5 * (M[7] - M[5]);
        J[k + c] = 0.5 * (M[2] - M[6]);
        J[2 * k + c] = 0.5 * (M[3] - M[1]);
        for (int r = 0; r < 3; r++) w[r] += J[r * k + c] * xdot[c];
    }
    double cr = cos(z[6]), sr = sin(z[6]), cp = cos(z[7]), sp = sin(z[7]);
    double cy = cos(z[8]), sy = sin(z[8]);
    double Rmeas[9] = {cy * cp,
                       cy * sp * sr - sy * cr,
                       cy * sp * cr + sy * sr,
                       sy * cp,
                       sy * sp * sr + cy * cr,
                       sy * sp * cr - cy * sr,
                       -sp,
                       cp * sr,
                       cp * cr};
    double T[9], v[3];
    for (int a = 0; a < 3; a++)
        for (int b = 0; b < 3; b++) {
            double s = 0.0;
            for (int j = 0; j < 3; j++) s += Rmeas[a * 3 + j] * R[b * 3 + j];
            T[a * 3 + b] = s;
        }
    rotation_log(T, v);
    double E[9] = {cy * cp, -sy, 0.0, sy * cp, cy, 0.0, -sp, 0.0, 1.0};
    for (int r = 0; r < 3; r++) {
        double* row = H + (6 + r) * n;
        for (int64_t c = 0; c < n; c++) row[c] = 0.0;
        for (int64_t c = 0; c < k; c++) row[cols[c]] = J[r * k + c];
        zo[6 + r] = v[r] + lag * w[r];
        hx[6 + r] = 0.0;
        for (int c = 0; c < 3; c++) {
            double ee =
                E[r * 3] * E[c * 3] + E[r * 3 + 1] * E[c * 3 + 1] + E[r * 3 + 2] * E[c * 3 + 2];
            Rm[(6 + r) * 9 + 6 + c] =
                sa * sa * (ee + (r == c ? floor_ * floor_ : 0.0)) + tau * tau * w[r] * w[c];
        }
    }
}

/* ---- The estimator's measurement update (gyrohost.estimator.fusion, fast path) ---- */

/* In-place Cholesky factor as numpy's (any positive, finite pivot); row + 1 where it fails. */
static int64_t cholesky_plain(double* A, int64_t n) {
    for (int64_t j = 0; j < n; j++) {
        double d = A[j * n + j];
        for (int64_t k = 0; k < j; k++) d -= A[j * n + k] * A[j * n + k];
        if (!(d > 0.0) || !isfinite(d)) return j + 1;
        d = sqrt(d);
        A[j * n + j] = d;
        for (int64_t i = j + 1; i < n; i++) {
            double s = A[i * n + j];
            for (int64_t k = 0; k < j; k++) s -= A[i * n + k] * A[j * n + k];
            A[i * n + j] = s / d;
        }
    }
    return 0;
}

/* log det of the k x k block of A (leading dimension ld) at (o, o), factored into blk: NaN
 * where it is not positive definite. */
static double block_log_det(const double* A, int64_t ld, int64_t o, int64_t k, double* blk) {
    for (int64_t i = 0; i < k; i++)
        for (int64_t j = 0; j < k; j++) blk[i * k + j] = A[(o + i) * ld + o + j];
    if (cholesky_plain(blk, k)) return NAN;
    double s = 0.0;
    for (int64_t i = 0; i < k; i++) s += log(blk[i * k + i]);
    return 2.0 * s;
}

#define MAX_ROWS 64 /* measurement rows of one update */

static int64_t update_work(int64_t n, int64_t M) {
    return 5 * n * M + 4 * M * M + 2 * M + 3 * n * n;
}

/* The gated update of k measurements stacked (sizes[i] rows each; M in all): H (M x n),
 * innovations y (M), block-diagonal noise R (M x M), gates (k, the NIS thresholds). Per
 * measurement: S_i = H_i P H_i^T + R_i, its diagonal (Sd), whitened innovation w_i = L_i^-1 y_i
 * (S_i = L_i L_i^T; NaN where not positive definite), stats[3 i ..] = (NIS, log det S_i - log
 * det R_i, accepted: NIS <= gate). The accepted ones are fused in one update: gain K = P H^T
 * S^-1 by one Cholesky of their S, x + K y, Joseph form (I - K H) P (I - K H)^T + K R K^T.
 * Status 0; k > 0: their S was not positive definite (xo, Po unset). */
static int64_t kalman_update(int64_t k, const int64_t* sizes, const double* gates, int64_t n,
                             int64_t M, const double* H, const double* y, const double* R,
                             const double* P, const double* x, double* Sd, double* w, double* stats,
                             double* xo, double* Po, double* work) {
    double *PHt = work, *S = PHt + n * M, *blk = S + M * M, *Sa = blk + M * M, *Ra = Sa + M * M;
    double *Ha = Ra + M * M, *PHa = Ha + M * n, *ya = PHa + n * M, *K = ya + M, *IKH = K + n * M;
    double *T = IKH + n * n, *KR = T + n * n;
    int64_t rows[MAX_ROWS], na = 0, o = 0;
    int in = (int)n, iM = (int)M;
    gemm(1, in, iM, in, 1.0, P, in, H, in, 0.0, PHt, iM);
    gemm(0, iM, iM, in, 1.0, H, in, PHt, iM, 0.0, S, iM);
    for (int64_t i = 0; i < M * M; i++) S[i] += R[i];
    for (int64_t i = 0; i < k; i++) {
        int64_t ki = sizes[i];
        for (int64_t r = 0; r < ki; r++) Sd[o + r] = S[(o + r) * M + o + r];
        double log_det_S = block_log_det(S, M, o, ki, blk), nis = 0.0;
        for (int64_t r = 0; r < ki; r++) { /* forward substitution, blk = L_i */
            double v = y[o + r];
            for (int64_t c = 0; c < r; c++) v -= blk[r * ki + c] * w[o + c];
            w[o + r] = isnan(log_det_S) ? NAN : v / blk[r * ki + r];
            nis += w[o + r] * w[o + r];
        }
        double ratio = nis / gates[i];
        int accepted = isfinite(ratio) && ratio <= 1.0;
        stats[3 * i] = nis;
        stats[3 * i + 1] = log_det_S - block_log_det(R, M, o, ki, blk);
        stats[3 * i + 2] = accepted;
        for (int64_t r = 0; accepted && r < ki; r++) rows[na++] = o + r;
        o += ki;
    }
    for (int64_t i = 0; i < n; i++) xo[i] = x[i];
    for (int64_t i = 0; i < n * n; i++) Po[i] = P[i];
    if (!na) return 0;
    for (int64_t a = 0; a < na; a++) {
        ya[a] = y[rows[a]];
        for (int64_t b = 0; b < na; b++) {
            Sa[a * na + b] = S[rows[a] * M + rows[b]];
            Ra[a * na + b] = R[rows[a] * M + rows[b]];
        }
        for (int64_t c = 0; c < n; c++) Ha[a * n + c] = H[rows[a] * n + c];
    }
    for (int64_t r = 0; r < n; r++)
        for (int64_t a = 0; a < na; a++) PHa[r * na + a] = PHt[r * M + rows[a]];
    int64_t status = cholesky_plain(Sa, na);
    if (status) return status;
    for (int64_t r = 0; r < n; r++) { /* K = P H^T S^-1, row by row (S symmetric) */
        for (int64_t a = 0; a < na; a++) K[r * na + a] = PHa[r * na + a];
        cholesky_subst(Sa, K + r * na, na);
        for (int64_t a = 0; a < na; a++) xo[r] += K[r * na + a] * ya[a];
    }
    int ia = (int)na;
    gemm(0, in, in, ia, -1.0, K, ia, Ha, in, 0.0, IKH, in);
    for (int64_t i = 0; i < n; i++) IKH[i * n + i] += 1.0;
    gemm(0, in, in, in, 1.0, IKH, in, P, in, 0.0, T, in);
    gemm(1, in, in, in, 1.0, T, in, IKH, in, 0.0, Po, in);
    gemm(0, in, ia, ia, 1.0, K, ia, Ra, ia, 0.0, KR, ia);
    gemm(1, in, in, ia, 1.0, KR, ia, K, ia, 1.0, Po, in);
    return 0;
}

/* ---- One IMU sample's cycle (gyrohost.estimator.fast_cycle) ----
 * The filter's fuse_imu in one call, the stages above in the filter's order: the lean step of
 * dt (none where dt = 0) with the process noise Q (nq x nq, nq <= n) on P's leading block, the
 * state onto the bars; the IMU's prediction there (its wheel accelerations at the step's end
 * setpoints); the three measurements; their gated update; the posterior onto the bars where one was
 * fused. spec (doubles): [step spec (step_spec_size), the IMU's constants (gravity, R_bs, rows,
 * N_fix: 21
 * + 3 m, as imu_predict's spec), the measurements' spec (8, imu_measurements'), z (9), gates
 * (3), rotation tolerance, manifold rtol, manifold iterations]. out: innovations (9), their
 * variances (9), whitened (9), stats (3 x 3, kalman_update's). Status 0; anything else: a stage
 * refused (a singular model, a non-finite value, axes that are no rotation, a Gram matrix or an
 * S not positive definite), the outputs unset: the caller takes the stages one by one. */
#define CYCLE_TAIL 23

static int64_t cycle_spec_size(const int64_t* d) {
    return step_spec_size(d) + 21 + 3 * d[0] + CYCLE_TAIL;
}

static int64_t cycle_work(const int64_t* d, int64_t n) {
    int64_t m = d[0], D = 6 * m + d[3] + d[2], scratch = lean_work(d, n);
    const int64_t other[3] = {imu_work(d), manifold_work(m, d[1], n), update_work(n, 9)};
    for (int i = 0; i < 3; i++) scratch = other[i] > scratch ? other[i] : scratch;
    return 2 * n + 2 * n * n + D * D + imu_spec_size(d) + 16 * D + 9 * n + 114 + scratch;
}

static int all_finite(const double* v, int64_t len) {
    for (int64_t i = 0; i < len; i++)
        if (!isfinite(v[i])) return 0;
    return 1;
}

/* Whether x (n) and the diagonal of P (n x n) are finite (a non-finite entry of P reaches the
 * diagonal within a step). */
static int state_finite(const double* x, const double* P, int64_t n) {
    for (int64_t i = 0; i < n; i++)
        if (!isfinite(x[i]) || !isfinite(P[i * n + i])) return 0;
    return 1;
}

/* imu_predict's spec at the step's end: its wheels' accelerations as the step's last stage
 * sees them, the IMU's constants ic (21 + 3 m). */
static void cycle_imu_spec(const int64_t* d, const StepSpec* p, const double* ic, const double* x,
                           double* is) {
    int64_t m = d[0], alpha = d[2], nw = d[3];
    double reach = p->wheel_accel * p->dt;
    is[0] = p->servo_lag;
    is[1] = p->follow ? -1.0 / p->wheel_lag : 0.0;
    for (int64_t i = 0; i < alpha; i++) is[2 + i] = p->rest_cmd[i];
    for (int64_t i = 0; i < nw; i++) {
        double step = p->cmd[i] - p->sp0[i];
        step = step > reach ? reach : (step < -reach ? -reach : step);
        is[2 + alpha + i] =
            p->follow ? (p->sp0[i] + step - x[6 * m + i]) / p->wheel_lag : p->wheel_acc[i];
    }
    for (int64_t i = 0; i < 21 + 3 * m; i++) is[2 + alpha + nw + i] = ic[i];
    is[imu_spec_size(d) - 1] = p->kink_sd;
}

/* The IMU's prediction at the prior xs and its checks (fuse_imu's): finite, R a rotation to
 * tol. f, R, ...: D, 9, 9 x D, 3, 3 x D, 3, 3 x D consecutive from f. */
static int64_t cycle_prediction(const Consts* k, const int64_t* d, const double* is,
                                const double* xs, double tol, double* A, double* f, double* w) {
    int64_t D = 6 * d[0] + d[3] + d[2];
    double *R = f + D, *dR = R + 9, *om = dR + 9 * D, *dom = om + 3, *fs = dom + 3 * D;
    int64_t status = imu_predict(k, d, is, xs, f, A, R, dR, om, dom, fs, fs + 3, w);
    if (status) return status;
    if (!all_finite(f, 16 * D + 15) || !all_finite(A, D * D)) return 1;
    for (int a = 0; a < 3; a++) {
        for (int c = 0; c < 3; c++) {
            double s = R[a] * R[c] + R[3 + a] * R[3 + c] + R[6 + a] * R[6 + c] - (a == c);
            if (fabs(s) > tol) return 1;
        }
    }
    return 0;
}

static int64_t imu_cycle(const Consts* k, const int64_t* d, const double* spec, const int64_t* cols,
                         const Bars* b, const double* x, const double* P, const double* Ain,
                         const double* Q, int64_t nq, double* xo, double* Po, double* A,
                         double* out, double* w) {
    int64_t m = d[0], D = 6 * m + d[3] + d[2], n = b->n, status;
    StepSpec p;
    step_spec(spec, d, &p);
    const double *ic = spec + step_spec_size(d), *ms = ic + 21 + 3 * m, *z = ms + 8;
    const double *gates = z + 9, tol = gates[3], rtol = gates[4];
    int64_t iterations = (int64_t)gates[5];
    double *xs = w, *Ps = xs + n, *xu = Ps + n * n, *Pu = xu + n, *F = Pu + n * n;
    double *is = F + D * D, *f = is + imu_spec_size(d), *H = f + 16 * D + 15, *hx = H + 9 * n;
    double *zo = hx + 9, *Rm = zo + 9, *scratch = Rm + 81, *stats = out + 27;
    for (int64_t i = 0; i < n; i++) xs[i] = x[i];
    for (int64_t i = 0; i < n * n; i++) Ps[i] = P[i];
    if (p.dt > 0.0) {
        status = lean_step(k, d, &p, n, x, P, Ain, xs, Ps, F, scratch);
        for (int64_t i = 0; !status && i < nq; i++)
            for (int64_t j = 0; j < nq; j++) Ps[i * n + j] += Q[i * nq + j];
        if (!status && !state_finite(xs, Ps, n)) status = 1;
        if (!status) status = project_bars(b, xs, rtol, iterations, scratch);
        if (status) return status;
    }
    cycle_imu_spec(d, &p, ic, xs, is);
    status = cycle_prediction(k, d, is, xs, tol, A, f, scratch);
    if (status) return status;
    const double* pred[7] = {
        f + D, f + D + 9, f + 10 * D + 9, f + 10 * D + 12, f + 13 * D + 12, f + 13 * D + 15, f};
    imu_measurements(n, D, cols, ms, pred, xs, z, H, hx, zo, Rm);
    for (int i = 0; i < 9; i++) out[i] = zo[i] - hx[i];
    const int64_t sizes[3] = {3, 3, 3};
    status = kalman_update(3, sizes, gates, n, 9, H, out, Rm, Ps, xs, out + 9, out + 18, stats, xu,
                           Pu, scratch);
    if (status) return status;
    int fused = stats[2] != 0.0 || stats[5] != 0.0 || stats[8] != 0.0;
    for (int64_t i = 0; i < n; i++) xo[i] = fused ? xu[i] : xs[i];
    if (!fused) {
        for (int64_t i = 0; i < n * n; i++) Po[i] = Ps[i];
        return 0;
    }
    status = condition_bars(b, xo, Pu, Po, rtol, iterations, scratch);
    return status ? status : !state_finite(xo, Po, n);
}

/* ---- The rig-fidelity model (gyrotensegrity.fast_rig; rigfidelity.py has the derivation) ----
 * dims (int64): [m, beta, alpha, n_w, n_tq, k, n_h], then the bar of each wheel (n_w), the wheel
 * of each torque input (n_tq), the bars with an axial state (k), the bar and the axial slot of
 * each hinge side (2 n_h each: the sides i of all hinges, then the sides j) and each torque
 * wheel's reaction slot (n_tq; -1: no reaction). consts: EE_T, off, k_s, c_s, WU, Ef as the
 * paper's kernel, then 1/l^3 (beta), J_3 of each wheel (n_w), the speed mask (n_w), the
 * reduced mass matrix's inverse (m x m), J_s (k), 1/J_3 of each torque wheel (n_tq), the hinge
 * axes in their bars' frames (3 x 2 n_h), the sides' signs (2 n_h) and the rank cut rcond. */
typedef struct {
    int64_t m, beta, alpha, nw, ntq, k, nh, K, D, r;
    const int64_t *wbar, *tq, *rbar, *sbar, *sslot, *react;
    const double *inv_l3, *J3w, *smask, *Minv, *Js, *invJ3, *axis, *sign;
    double rcond;
    Consts paper; /* the members member_vectors and reduced_forces read */
} Rig;

// clang-format off
static void rig_layout(const double *c, const int64_t *d, Rig *g)
{
    g->m = d[0]; g->beta = d[1]; g->alpha = d[2]; g->nw = d[3]; g->ntq = d[4];
    g->k = d[5]; g->nh = d[6];
    g->K = g->beta + g->alpha; g->D = 3 * g->m + g->k; g->r = g->beta + 3 * g->nh;
    const int64_t *i = d + 7, m = g->m, K = g->K, al = g->alpha, nw = g->nw, s2 = 2 * g->nh;
    g->wbar = i; i += nw;
    g->tq = i; i += g->ntq;
    g->rbar = i; i += g->k;
    g->sbar = i; i += s2;
    g->sslot = i; i += s2;
    g->react = i;
    g->paper.EE_T = c; c += m * K;
    g->paper.off = c; c += 3 * K;
    g->paper.k_s = c; c += al;
    g->paper.c_s = c; c += al;
    g->paper.WU = c; c += 3 * m;
    g->paper.Ef = c; c += K * m;
    g->inv_l3 = c; c += g->beta;
    g->J3w = c; c += nw;
    g->smask = c; c += nw;
    g->Minv = c; c += m * m;
    g->Js = c; c += g->k;
    g->invJ3 = c; c += g->ntq;
    g->axis = c; c += 3 * s2;
    g->sign = c; c += s2;
    g->rcond = *c;
}
// clang-format on

static int64_t rig_work(const int64_t* d) {
    int64_t K = d[1] + d[2], D = 3 * d[0] + d[5], r = d[1] + 3 * d[6];
    return 9 * K + 3 * D + d[3] + d[1] + 2 * r * D + r * r + 4 * r;
}

static void cross3(const double* a, const double* b, double* c) {
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static double dot3(const double* a, const double* b) {
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* Column j of a 3 x K row-major array into v. */
static void column3(const double* A, int64_t K, int64_t j, double* v) {
    for (int r = 0; r < 3; r++) v[r] = A[r * K + j];
}

/* b_hat and d/dt (b / |b|) of a bar vector b with rate bd; returns |b|^2. */
static double unit_rate(const double* b, const double* bd, double* bh, double* bhd) {
    double l2 = dot3(b, b), len = sqrt(l2);
    for (int r = 0; r < 3; r++) bh[r] = b[r] / len;
    double along = dot3(bh, bd);
    for (int r = 0; r < 3; r++) bhd[r] = (bd[r] - bh[r] * along) / len;
    return l2;
}

/* One hinge side s (bar p): its three rows of G (added at row0, D columns) and of gamma. */
static void hinge_side(const Rig* g, const double* pos, const double* vel, const double* wax,
                       const double* e, int64_t s, double* G, double* gam) {
    int64_t m = g->m, K = g->K, D = g->D, p = g->sbar[s], slot = g->sslot[s], s2 = 2 * g->nh;
    int64_t row0 = g->beta + 3 * (s % g->nh);
    double b[3], bd[3], bh[3], bhd[3], ev[3], bxe[3], h[3], ax[3], bxbd[3], w[3], wd[3];
    double wh[3], wwh[3], t1[3];
    column3(pos, K, p, b);
    column3(vel, K, p, bd);
    column3(e, g->k, slot, ev);
    double l2 = unit_rate(b, bd, bh, bhd), sg = g->sign[s];
    cross3(bh, ev, bxe);
    for (int r = 0; r < 3; r++)
        h[r] = g->axis[s] * bh[r] + g->axis[s2 + s] * ev[r] + g->axis[2 * s2 + s] * bxe[r];
    double hb = dot3(h, b);
    /* (b x b_ddot) x h / |b|^2 = ((h . b) I - b h^T) b_ddot / |b|^2 */
    for (int rr = 0; rr < 3; rr++) {
        for (int c = 0; c < 3; c++) {
            double A = sg / l2 * ((rr == c ? hb : 0.0) - b[rr] * h[c]);
            double* row = G + (row0 + rr) * D + c * m;
            for (int64_t j = 0; j < m; j++) row[j] += A * g->paper.EE_T[j * K + p];
        }
    }
    cross3(bh, h, ax);
    for (int rr = 0; rr < 3; rr++) G[(row0 + rr) * D + 3 * m + slot] += sg * ax[rr];
    cross3(b, bd, bxbd);
    double bbd = dot3(b, bd);
    for (int r = 0; r < 3; r++) {
        w[r] = bxbd[r] / l2 + wax[slot] * bh[r];
        wd[r] = -2.0 * bbd * bxbd[r] / (l2 * l2) + wax[slot] * bhd[r];
    }
    cross3(wd, h, t1);
    cross3(w, h, wh);
    cross3(w, wh, wwh);
    for (int r = 0; r < 3; r++) gam[row0 + r] += sg * (t1[r] + wwh[r]);
}

/* G (r x D, row-major) and gamma (r): bar lengths (b . b_dot), then three rows per hinge. */
static void rig_constraints(const Rig* g, const double* pos, const double* vel, const double* wax,
                            const double* e, double* G, double* gam) {
    int64_t m = g->m, K = g->K, D = g->D;
    for (int64_t i = 0; i < g->r * D; i++) G[i] = 0.0;
    for (int64_t i = 0; i < g->r; i++) gam[i] = 0.0;
    for (int64_t i = 0; i < g->beta; i++) {
        double b[3], bd[3];
        column3(pos, K, i, b);
        column3(vel, K, i, bd);
        for (int c = 0; c < 3; c++)
            for (int64_t j = 0; j < m; j++) G[i * D + c * m + j] = b[c] * g->paper.EE_T[j * K + i];
        gam[i] = dot3(bd, bd);
    }
    for (int64_t s = 0; s < 2 * g->nh; s++) hinge_side(g, pos, vel, wax, e, s, G, gam);
}

/* y = M^-1 v for generalized forces v (D): kron(I3, M_red^-1), then 1/J_s. */
static void rig_mass_solve(const Rig* g, const double* v, double* y) {
    int64_t m = g->m;
    for (int c = 0; c < 3; c++) {
        for (int64_t i = 0; i < m; i++) {
            double s = 0.0;
            for (int64_t j = 0; j < m; j++) s += g->Minv[i * m + j] * v[c * m + j];
            y[c * m + i] = s;
        }
    }
    for (int64_t s = 0; s < g->k; s++) y[3 * m + s] = v[3 * m + s] / g->Js[s];
}

/* Swap rows and columns i and j of the n x n matrix A. */
static void swap_symmetric(double* A, int64_t n, int64_t i, int64_t j) {
    for (int64_t c = 0; c < n; c++) {
        double t = A[i * n + c];
        A[i * n + c] = A[j * n + c];
        A[j * n + c] = t;
    }
    for (int64_t c = 0; c < n; c++) {
        double t = A[c * n + i];
        A[c * n + i] = A[c * n + j];
        A[c * n + j] = t;
    }
}

/* mu (n) with A mu = b for a symmetric positive semi-definite A (n x n, overwritten) and a b
 * outside A's null space: Cholesky with complete pivoting (LAPACK's dpstrf) up to the first
 * pivot at or below rcond times A's largest diagonal entry; the multipliers of the rows beyond
 * (redundant constraints) are 0. w: 2 n doubles of work. */
static void semidefinite_solve(double* A, const double* b, double* mu, double* w, int64_t n,
                               double rcond) {
    double *perm = w, *y = w + n, tol = 0.0;
    for (int64_t i = 0; i < n; i++) {
        tol = fmax(tol, A[i * n + i]);
        perm[i] = (double)i;
    }
    tol *= rcond;
    int64_t rank = n;
    for (int64_t j = 0; j < n; j++) {
        int64_t p = j;
        for (int64_t i = j + 1; i < n; i++)
            if (A[i * n + i] > A[p * n + p]) p = i;
        if (!(A[p * n + p] > tol)) {
            rank = j;
            break;
        }
        if (p != j) {
            swap_symmetric(A, n, j, p);
            double t = perm[j];
            perm[j] = perm[p];
            perm[p] = t;
        }
        double d = sqrt(A[j * n + j]);
        A[j * n + j] = d;
        for (int64_t i = j + 1; i < n; i++) A[i * n + j] /= d;
        for (int64_t i = j + 1; i < n; i++)
            for (int64_t l = j + 1; l < n; l++) A[i * n + l] -= A[i * n + j] * A[l * n + j];
    }
    for (int64_t i = 0; i < rank; i++) y[i] = b[(int64_t)perm[i]];
    cholesky_subst_ld(A, n, y, rank);
    for (int64_t i = 0; i < n; i++) mu[i] = 0.0;
    for (int64_t i = 0; i < rank; i++) mu[(int64_t)perm[i]] = y[i];
}

/* Spins of the wheels (n_w) and the generalized forces Q (D): the paper's strings and gyroscopic
 * couples with each bar's whole axial momentum, the motor reactions on the stators' bars. */
static void rig_forces(const Rig* g, const int64_t* d, const double* x, const double* u,
                       double* pos, double* vel, double* cols, double* omega, double* H,
                       double* Q) {
    int64_t m = g->m, beta = g->beta, K = g->K, nw = g->nw;
    const double *wax = x + 6 * m + nw + g->ntq, *uw = u + g->alpha;
    member_vectors(&g->paper, d, x, x + 3 * m, pos, vel);
    for (int64_t i = 0; i < nw; i++) omega[i] = g->smask[i] * uw[i];
    for (int64_t t = 0; t < g->ntq; t++) omega[g->tq[t]] = x[6 * m + nw + t];
    for (int64_t i = 0; i < beta; i++) H[i] = 0.0;
    for (int64_t i = 0; i < nw; i++) H[g->wbar[i]] = g->J3w[i] * omega[i];
    for (int64_t s = 0; s < g->k; s++) H[g->rbar[s]] += g->Js[s] * wax[s];
    for (int64_t i = 0; i < beta; i++) {
        double b[3], bd[3], c[3];
        column3(pos, K, i, b);
        column3(vel, K, i, bd);
        cross3(b, bd, c);
        for (int r = 0; r < 3; r++) cols[r * K + i] = c[r] * H[i] * g->inv_l3[i];
    }
    for (int64_t j = beta; j < K; j++) {
        double S[3], Sd[3];
        column3(pos, K, j, S);
        column3(vel, K, j, Sd);
        double s = sqrt(dot3(S, S)), rest = u[j - beta];
        double tension =
            g->paper.k_s[j - beta] * (s - rest) + g->paper.c_s[j - beta] * dot3(S, Sd) / s;
        double gamma = (s > rest && tension > 0.0) ? tension / s : 0.0;
        for (int r = 0; r < 3; r++) cols[r * K + j] = S[r] * gamma;
    }
    reduced_forces(&g->paper, d, cols, Q);
    for (int64_t s = 0; s < g->k; s++) Q[3 * m + s] = 0.0;
    for (int64_t t = 0; t < g->ntq; t++)
        if (g->react[t] >= 0) Q[3 * m + g->react[t]] -= uw[g->tq[t]];
}

/* dx/dt of the rig-fidelity model (state and layout of rigfidelity.RigFidelity.rhs): M a = Q +
 * G^T mu, G a = -gamma, solved as K mu = -gamma - G M^-1 Q with K = G M^-1 G^T. */
static void rig_evaluate(const Rig* g, const int64_t* d, const double* x, const double* u,
                         double* out, double* w) {
    int64_t m = g->m, K = g->K, D = g->D, r = g->r, nw = g->nw, ntq = g->ntq, k = g->k;
    double *pos = w, *vel = pos + 3 * K, *cols = vel + 3 * K, *Q = cols + 3 * K, *a0 = Q + D;
    double *a = a0 + D, *omega = a + D, *H = omega + nw, *G = H + g->beta, *MG = G + r * D;
    double *Km = MG + r * D, *gam = Km + r * r, *mu = gam + r, *sw = mu + r;
    const double *wax = x + 6 * m + nw + ntq, *e = wax + k;
    rig_forces(g, d, x, u, pos, vel, cols, omega, H, Q);
    rig_constraints(g, pos, vel, wax, e, G, gam);
    rig_mass_solve(g, Q, a0);
    for (int64_t i = 0; i < r; i++)
        rig_mass_solve(g, G + i * D, MG + i * D); /* rows: (M^-1 G^T)^T */
    for (int64_t i = 0; i < r; i++) {
        double s = -gam[i];
        for (int64_t c = 0; c < D; c++) s -= G[i * D + c] * a0[c];
        gam[i] = s;
        for (int64_t j = 0; j < r; j++) {
            double t = 0.0;
            for (int64_t c = 0; c < D; c++) t += G[i * D + c] * MG[j * D + c];
            Km[i * r + j] = t;
        }
    }
    semidefinite_solve(Km, gam, mu, sw, r, g->rcond);
    for (int64_t c = 0; c < D; c++) {
        double s = a0[c];
        for (int64_t i = 0; i < r; i++) s += MG[i * D + c] * mu[i];
        a[c] = s;
    }
    for (int64_t i = 0; i < 3 * m; i++) {
        out[i] = x[3 * m + i];
        out[3 * m + i] = a[i];
    }
    for (int64_t i = 0; i < nw; i++) out[6 * m + i] = omega[i];
    for (int64_t t = 0; t < ntq; t++) out[6 * m + nw + t] = u[g->alpha + g->tq[t]] * g->invJ3[t];
    double* tail = out + 6 * m + nw + ntq;
    for (int64_t s = 0; s < k; s++) {
        double b[3], bd[3], bh[3], bhd[3], ev[3], bxe[3];
        column3(pos, K, g->rbar[s], b);
        column3(vel, K, g->rbar[s], bd);
        column3(e, k, s, ev);
        unit_rate(b, bd, bh, bhd);
        cross3(bh, ev, bxe);
        double along = dot3(bhd, ev);
        tail[s] = a[3 * m + s];
        for (int c = 0; c < 3; c++) tail[k + c * k + s] = -bh[c] * along + wax[s] * bxe[c];
    }
}

/* The buffers of a call: the first n_read read, the rest up to n written. */
static int get_buffer_list(PyObject* const* args, Py_ssize_t nargs, Py_buffer* buf, int n_read,
                           int n, const char* use) {
    if (nargs != n) {
        PyErr_SetString(PyExc_TypeError, use);
        return -1;
    }
    int got = 0;
    for (; got < n; got++) {
        int flags = (got >= n_read) ? PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS : PyBUF_C_CONTIGUOUS;
        if (PyObject_GetBuffer(args[got], &buf[got], flags) < 0) break;
    }
    if (got == n) return 0;
    for (int i = 0; i < got; i++) PyBuffer_Release(&buf[i]);
    return -1;
}

/* The six buffers of a call: the first four read, the last two written. */
static int get_buffers(PyObject* const* args, Py_ssize_t nargs, Py_buffer* buf, const char* use) {
    return get_buffer_list(args, nargs, buf, 4, 6, use);
}

/* A call's body: it checks its buffers (-1 with a Python error where they do not fit) and
 * computes; the status it returns goes back to Python. */
typedef int64_t (*CallBody)(Py_buffer* buf);

static PyObject* buffer_call(PyObject* const* args, Py_ssize_t nargs, int n_read, int n,
                             const char* use, CallBody body) {
    Py_buffer buf[16];
    if (get_buffer_list(args, nargs, buf, n_read, n, use) < 0) return NULL;
    int64_t status = body(buf);
    for (int i = 0; i < n; i++) PyBuffer_Release(&buf[i]);
    return status < 0 ? NULL : PyLong_FromLongLong(status);
}

/* A module function taking n buffers (the first n_read read) into body. */
#define BUFFER_CALL(name, n_read, n, use, body)                                      \
    static PyObject* name(PyObject* self, PyObject* const* args, Py_ssize_t nargs) { \
        (void)self;                                                                  \
        return buffer_call(args, nargs, n_read, n, use, body);                       \
    }

/* Whether ok and buffers from..n-1 hold need[i] doubles each; a ValueError saying what where
 * not. */
static int fits(const Py_buffer* buf, const int64_t* need, int from, int n, int ok,
                const char* what) {
    for (int i = from; i < n; i++) ok = ok && buf[i].len >= need[i] * (Py_ssize_t)sizeof(double);
    if (!ok) PyErr_SetString(PyExc_ValueError, what);
    return ok;
}

#define RIG_USE "rig_rhs(consts, dims, x, u, out, work) takes 6 buffers"

static int64_t rig_body(Py_buffer* buf) {
    const int64_t* d = (const int64_t*)buf[1].buf;
    if (buf[1].len < 7 * (Py_ssize_t)sizeof(int64_t)) {
        PyErr_SetString(PyExc_ValueError, "rig_rhs: dims holds fewer than 7 sizes");
        return -1;
    }
    int64_t n = 6 * d[0] + d[3] + d[4] + 4 * d[5];
    const int64_t need[6] = {0, 0, n, d[2] + d[3], n, rig_work(d)};
    if (!fits(buf, need, 2, 6, 1, "rig_rhs: a small buffer")) return -1;
    Rig g;
    rig_layout((const double*)buf[0].buf, d, &g);
    Py_BEGIN_ALLOW_THREADS rig_evaluate(&g, d, (const double*)buf[2].buf, (const double*)buf[3].buf,
                                        (double*)buf[4].buf, (double*)buf[5].buf);
    Py_END_ALLOW_THREADS return 0;
}

BUFFER_CALL(kernel_rig_rhs, 4, 6, RIG_USE, rig_body)

#define LEAN_USE "lean_step(consts, dims, spec, x, P, A, x_out, P_out, F, work) takes 10 buffers"

static int64_t lean_body(Py_buffer* buf) {
    const int64_t* dims = (const int64_t*)buf[1].buf;
    int64_t m = dims[0], D = 6 * m + dims[3] + dims[2], status;
    int64_t n = (int64_t)(buf[3].len / (Py_ssize_t)sizeof(double));
    const int64_t need[10] = {0,     0,     step_spec_size(dims), n, n * n, D * D, n,
                              n * n, D * D, lean_work(dims, n)};
    if (!fits(buf, need, 2, 10, dims[5] == 0 && n >= D, "lean_step: joints, or a small buffer"))
        return -1;
    Consts k;
    StepSpec spec;
    layout((const double*)buf[0].buf, dims, &k);
    step_spec((const double*)buf[2].buf, dims, &spec);
    Py_BEGIN_ALLOW_THREADS status =
        lean_step(&k, dims, &spec, n, (const double*)buf[3].buf, (const double*)buf[4].buf,
                  (const double*)buf[5].buf, (double*)buf[6].buf, (double*)buf[7].buf,
                  (double*)buf[8].buf, (double*)buf[9].buf);
    Py_END_ALLOW_THREADS return status;
}

BUFFER_CALL(kernel_lean_step, 6, 10, LEAN_USE, lean_body)

/* use_blas(capsule): take dgemm from scipy.linalg.cython_blas.__pyx_capi__["dgemm"]. */
static PyObject* kernel_use_blas(PyObject* self, PyObject* capsule) {
    (void)self;
    if (capsule == Py_None) { /* back to the loops */
        blas_dgemm = NULL;
        Py_RETURN_NONE;
    }
    const char* name = PyCapsule_GetName(capsule);
    if (!name) return NULL;
    const char* want = "void (char *, char *, int *, int *, int *, ";
    if (strncmp(name, want, strlen(want)) != 0 || !strstr(name, "_d *")) {
        PyErr_Format(PyExc_ValueError, "use_blas: not a double dgemm: %s", name);
        return NULL;
    }
    void* fn = PyCapsule_GetPointer(capsule, name);
    if (!fn) return NULL;
    blas_dgemm = (dgemm_fn)fn;
    Py_RETURN_NONE;
}

#define MANIFOLD_USE                                                                         \
    "manifold(E, B0, l2, spec, P, x, P_out, work) takes 8 buffers (P, P_out empty: project " \
    "the state alone)"

/* manifold(E, B0, l2, spec, P, x, P_out, work) -> status: x projected in place onto the bars'
 * constraints and, unless P is empty, P_out = Pi P Pi^T; spec = [rtol, iterations]. */
static int64_t manifold_body(Py_buffer* buf) {
    Py_ssize_t w = (Py_ssize_t)sizeof(double);
    Bars b;
    b.beta = (int64_t)(buf[2].len / w);
    b.m = b.beta ? (int64_t)(buf[0].len / w) / b.beta : 0;
    b.n = (int64_t)(buf[5].len / w);
    b.E = (const double*)buf[0].buf;
    b.B0 = (const double*)buf[1].buf;
    b.l2 = (const double*)buf[2].buf;
    const double* spec = (const double*)buf[3].buf;
    int with_P = buf[4].len > 0;
    int64_t nn = with_P ? b.n * b.n : 0, status;
    const int64_t need[8] = {0, 3 * b.beta, 0, 2, nn, b.n, nn, manifold_work(b.m, b.beta, b.n)};
    if (!fits(buf, need, 1, 8, b.beta > 0 && b.n >= 6 * b.m, "manifold: a buffer is too small"))
        return -1;
    double* x = (double*)buf[5].buf;
    double* work = (double*)buf[7].buf;
    int64_t iterations = (int64_t)spec[1];
    Py_BEGIN_ALLOW_THREADS if (with_P) status = condition_bars(
        &b, x, (const double*)buf[4].buf, (double*)buf[6].buf, spec[0], iterations, work);
    else status = project_bars(&b, x, spec[0], iterations, work);
    Py_END_ALLOW_THREADS return status;
}

BUFFER_CALL(kernel_manifold, 5, 8, MANIFOLD_USE, manifold_body)

/* The n integers of a call into v; 0, or -1 with a Python error. */
static int int_args(PyObject* const* args, Py_ssize_t nargs, int n, long long* v, const char* use) {
    if (nargs != n) {
        PyErr_SetString(PyExc_TypeError, use);
        return -1;
    }
    for (int i = 0; i < n; i++) {
        v[i] = PyLong_AsLongLong(args[i]);
        if (v[i] == -1 && PyErr_Occurred()) return -1;
    }
    return 0;
}

static PyObject* kernel_manifold_work(PyObject* self, PyObject* const* args, Py_ssize_t nargs) {
    (void)self;
    long long v[3];
    if (int_args(args, nargs, 3, v, "manifold_work(m, beta, n) takes 3 integers")) return NULL;
    return PyLong_FromLongLong(manifold_work(v[0], v[1], v[2]));
}

#define IMU_USE                                                                               \
    "imu(consts, dims, spec, x, f, A, R, dR, omega, d_omega, force, d_force, work) takes 13 " \
    "buffers"

static int64_t imu_body(Py_buffer* buf) {
    const int64_t* dims = (const int64_t*)buf[1].buf;
    int64_t m = dims[0], D = 6 * m + dims[3] + dims[2], status;
    const int64_t need[13] = {0, 0,     imu_spec_size(dims), D, D, D * D, 9, 9 * D, 3, 3 * D,
                              3, 3 * D, imu_work(dims)};
    if (!fits(buf, need, 2, 13, dims[5] == 0 && m <= 100,
              "imu: joints, over 100 coordinates or a small buffer"))
        return -1;
    Consts k;
    double* o[9];
    for (int i = 0; i < 9; i++) o[i] = (double*)buf[4 + i].buf;
    layout((const double*)buf[0].buf, dims, &k);
    Py_BEGIN_ALLOW_THREADS status =
        imu_predict(&k, dims, (const double*)buf[2].buf, (const double*)buf[3].buf, o[0], o[1],
                    o[2], o[3], o[4], o[5], o[6], o[7], o[8]);
    Py_END_ALLOW_THREADS return status;
}

BUFFER_CALL(kernel_imu, 4, 13, IMU_USE, imu_body)

#define UPDATE_USE                                                                               \
    "update(sizes, gates, H, y, R, P, x, S_diag, whitened, stats, x_out, P_out, work) takes 13 " \
    "buffers"

static int64_t update_body(Py_buffer* buf) {
    int64_t k = (int64_t)(buf[0].len / (Py_ssize_t)sizeof(int64_t)), M = 0, status;
    int64_t n = (int64_t)(buf[6].len / (Py_ssize_t)sizeof(double));
    const int64_t* sizes = (const int64_t*)buf[0].buf;
    for (int64_t i = 0; i < k; i++) M += sizes[i] > 0 ? sizes[i] : MAX_ROWS + 1;
    const int64_t need[13] = {
        0, k, M * n, M, M * M, n * n, n, M, M, 3 * k, n, n * n, update_work(n, M)};
    if (!fits(buf, need, 1, 13, M <= MAX_ROWS, "update: over 64 rows, or a small buffer"))
        return -1;
    const double* in[6];
    double* out[6];
    for (int i = 0; i < 6; i++) {
        in[i] = (const double*)buf[1 + i].buf;
        out[i] = (double*)buf[7 + i].buf;
    }
    Py_BEGIN_ALLOW_THREADS status =
        kalman_update(k, sizes, in[0], n, M, in[1], in[2], in[3], in[4], in[5], out[0], out[1],
                      out[2], out[3], out[4], out[5]);
    Py_END_ALLOW_THREADS return status;
}

BUFFER_CALL(kernel_update, 7, 13, UPDATE_USE, update_body)

static PyObject* kernel_update_work(PyObject* self, PyObject* const* args, Py_ssize_t nargs) {
    (void)self;
    long long v[2];
    if (int_args(args, nargs, 2, v, "update_work(n, rows) takes 2 integers")) return NULL;
    return PyLong_FromLongLong(update_work(v[0], v[1]));
}

#define IMU_MEAS_USE                                                                           \
    "imu_measurements(cols, spec, R, dR, omega, d_omega, force, d_force, x_dot, x, z, H, hx, " \
    "z_out, R_out) takes 15 buffers"

static int64_t imu_measurements_body(Py_buffer* buf) {
    Py_ssize_t w = (Py_ssize_t)sizeof(double);
    int64_t k = (int64_t)(buf[0].len / (Py_ssize_t)sizeof(int64_t)), n = (int64_t)(buf[9].len / w);
    const int64_t need[15] = {0, 8, 9, 9 * k, 3, 3 * k, 3, 3 * k, k, n, 9, 9 * n, 9, 9, 81};
    const int64_t* cols = (const int64_t*)buf[0].buf;
    int ok = k <= 256;
    for (int64_t c = 0; ok && c < k; c++) ok = cols[c] >= 0 && cols[c] < n;
    if (!fits(buf, need, 1, 15, ok, "imu_measurements: a buffer too small or a column off"))
        return -1;
    const double* pred[7];
    for (int i = 0; i < 7; i++) pred[i] = (const double*)buf[2 + i].buf;
    imu_measurements(n, k, cols, (const double*)buf[1].buf, pred, (const double*)buf[9].buf,
                     (const double*)buf[10].buf, (double*)buf[11].buf, (double*)buf[12].buf,
                     (double*)buf[13].buf, (double*)buf[14].buf);
    return 0;
}

BUFFER_CALL(kernel_imu_measurements, 11, 15, IMU_MEAS_USE, imu_measurements_body)

#define CYCLE_USE                                                                                  \
    "imu_cycle(consts, dims, spec, cols, bars, x, P, A, Q, x_out, P_out, A_out, out, work) takes " \
    "14 buffers"

/* bars: the manifold's E (beta x m), B0 (3 x beta), l2 (beta) one after the other. */
static int64_t cycle_body(Py_buffer* buf) {
    const int64_t *dims = (const int64_t*)buf[1].buf, *cols = (const int64_t*)buf[3].buf;
    int64_t m = dims[0], beta = dims[1], D = 6 * m + dims[3] + dims[2], status;
    int64_t n = (int64_t)(buf[5].len / (Py_ssize_t)sizeof(double));
    int64_t nq = (int64_t)sqrt((double)(buf[8].len / (Py_ssize_t)sizeof(double)) + 0.5);
    const int64_t need[14] = {
        0,     0,  cycle_spec_size(dims), D, beta * (m + 4), n, n * n, D * D, nq * nq, n, n * n,
        D * D, 36, cycle_work(dims, n)};
    int ok = dims[5] == 0 && n >= D && m <= 100 && D <= 256 && beta > 0 && nq <= n &&
             buf[8].len == nq * nq * (Py_ssize_t)sizeof(double);
    for (int64_t c = 0; ok && c < D; c++) ok = cols[c] == c;
    if (!fits(buf, need, 2, 14, ok, "imu_cycle: joints, over 100 coordinates or a small buffer"))
        return -1;
    Consts k;
    layout((const double*)buf[0].buf, dims, &k);
    const double* bars = (const double*)buf[4].buf;
    Bars b = {m, beta, n, bars, bars + beta * m, bars + beta * (m + 3)};
    const double* in[5];
    double* o[5];
    for (int i = 0; i < 5; i++) {
        in[i] = (const double*)buf[i ? 4 + i : 2].buf; /* spec, x, P, A, Q */
        o[i] = (double*)buf[9 + i].buf;
    }
    Py_BEGIN_ALLOW_THREADS status = imu_cycle(&k, dims, in[0], cols, &b, in[1], in[2], in[3], in[4],
                                              nq, o[0], o[1], o[2], o[3], o[4]);
    Py_END_ALLOW_THREADS return status;
}

BUFFER_CALL(kernel_imu_cycle, 9, 14, CYCLE_USE, cycle_body)

/* A work size of the model's dims (an int64 buffer) and an n-entry filter state: (dims, n). */
static PyObject* dims_n_work(PyObject* const* args, Py_ssize_t nargs,
                             int64_t (*size)(const int64_t*, int64_t), const char* use) {
    Py_buffer dims;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, use);
        return NULL;
    }
    long long n = PyLong_AsLongLong(args[1]);
    if (n == -1 && PyErr_Occurred()) return NULL;
    if (PyObject_GetBuffer(args[0], &dims, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    int64_t need = size((const int64_t*)dims.buf, (int64_t)n);
    PyBuffer_Release(&dims);
    return PyLong_FromLongLong(need);
}

static PyObject* kernel_cycle_work(PyObject* self, PyObject* const* args, Py_ssize_t nargs) {
    (void)self;
    return dims_n_work(args, nargs, cycle_work, "cycle_work(dims, n) takes 2 arguments");
}

static PyObject* kernel_lean_work(PyObject* self, PyObject* const* args, Py_ssize_t nargs) {
    (void)self;
    return dims_n_work(args, nargs, lean_work, "lean_work(dims, n) takes 2 arguments");
}

static PyObject* kernel_jacobian(PyObject* self, PyObject* const* args, Py_ssize_t nargs) {
    (void)self;
    Py_buffer buf[6];
    if (get_buffers(args, nargs, buf,
                    "jacobian(consts, dims, state, acc, J, work) takes 6 "
                    "buffers") < 0)
        return NULL;
    const int64_t* dims = (const int64_t*)buf[1].buf;
    int64_t status = -1;
    if (dims[5] != 0 || buf[5].len < (Py_ssize_t)(jacobian_work(dims) * sizeof(double))) {
        PyErr_SetString(PyExc_ValueError, "jacobian: joints, or the work buffer is too small");
    } else {
        Consts k;
        layout((const double*)buf[0].buf, dims, &k);
        Py_BEGIN_ALLOW_THREADS status =
            jacobian(&k, dims, (const double*)buf[2].buf, (double*)buf[3].buf, (double*)buf[4].buf,
                     (double*)buf[5].buf);
        Py_END_ALLOW_THREADS
    }
    for (int i = 0; i < 6; i++) PyBuffer_Release(&buf[i]);
    return status < 0 ? NULL : PyLong_FromLongLong(status);
}

/* A work size of the model's dims (an int64 buffer). */
static PyObject* dims_work(PyObject* arg, int64_t (*size)(const int64_t*)) {
    Py_buffer dims;
    if (PyObject_GetBuffer(arg, &dims, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    int64_t n = size((const int64_t*)dims.buf);
    PyBuffer_Release(&dims);
    return PyLong_FromLongLong(n);
}

static PyObject* kernel_jacobian_work(PyObject* self, PyObject* arg) {
    (void)self;
    return dims_work(arg, jacobian_work);
}

static PyObject* kernel_imu_work(PyObject* self, PyObject* arg) {
    (void)self;
    return dims_work(arg, imu_work);
}

static PyObject* kernel_rig_work(PyObject* self, PyObject* arg) {
    (void)self;
    return dims_work(arg, rig_work);
}

static PyObject* kernel_rhs(PyObject* self, PyObject* const* args, Py_ssize_t nargs) {
    (void)self;
    Py_buffer buf[6];
    if (get_buffers(args, nargs, buf, "rhs(consts, dims, x, u, out, work) takes 6 buffers") < 0)
        return NULL;
    const int64_t* dims = (const int64_t*)buf[1].buf;
    Consts k;
    layout((const double*)buf[0].buf, dims, &k);
    int64_t status;
    Py_BEGIN_ALLOW_THREADS status =
        evaluate(&k, dims, (const double*)buf[2].buf, (const double*)buf[3].buf,
                 (double*)buf[4].buf, (double*)buf[5].buf);
    Py_END_ALLOW_THREADS for (int i = 0; i < 6; i++) PyBuffer_Release(&buf[i]);
    return PyLong_FromLongLong(status);
}

static PyMethodDef methods[] = {
    {"rhs", (PyCFunction)(void (*)(void))kernel_rhs, METH_FASTCALL,
     "rhs(consts, dims, x, u, out, work) -> status (0 ok, k > 0 singular at pivot k - 1)"},
    {"jacobian", (PyCFunction)(void (*)(void))kernel_jacobian, METH_FASTCALL,
     "jacobian(consts, dims, state, acc, J, work) -> status: accelerations and their Jacobian "
     "(dense path without joints; state [q, q_dot, omega_w, rest])"},
    {"lean_step", (PyCFunction)(void (*)(void))kernel_lean_step, METH_FASTCALL,
     "lean_step(consts, dims, spec, x, P, A, x_out, P_out, F, work) -> status: the estimator's "
     "lean prediction step (RK4 state, Taylor-series F, F P F^T)"},
    {"lean_work", (PyCFunction)(void (*)(void))kernel_lean_work, METH_FASTCALL,
     "lean_work(dims, n) -> doubles of work lean_step() needs for an n-entry filter state"},
    {"manifold", (PyCFunction)(void (*)(void))kernel_manifold, METH_FASTCALL,
     "manifold(E, B0, l2, spec, P, x, P_out, work) -> status: the filter state onto the bars' "
     "constraints (in place), P_out = Pi P Pi^T unless P is empty"},
    {"manifold_work", (PyCFunction)(void (*)(void))kernel_manifold_work, METH_FASTCALL,
     "manifold_work(m, beta, n) -> doubles of work manifold() needs"},
    {"imu", (PyCFunction)(void (*)(void))kernel_imu, METH_FASTCALL,
     "imu(consts, dims, spec, x, f, A, R, dR, omega, d_omega, force, d_force, work) -> status: "
     "the IMU's prediction and Jacobians with the dynamics' (the estimator's closed form)"},
    {"update", (PyCFunction)(void (*)(void))kernel_update, METH_FASTCALL,
     "update(sizes, gates, H, y, R, P, x, S_diag, whitened, stats, x_out, P_out, work) -> "
     "status: the gated Kalman update of stacked measurements (the estimator's fast path)"},
    {"update_work", (PyCFunction)(void (*)(void))kernel_update_work, METH_FASTCALL,
     "update_work(n, rows) -> doubles of work update() needs"},
    {"imu_measurements", (PyCFunction)(void (*)(void))kernel_imu_measurements, METH_FASTCALL,
     "imu_measurements(cols, spec, R, dR, omega, d_omega, force, d_force, x_dot, x, z, H, hx, "
     "z_out, R_out): the IMU's rate, specific force and attitude measurements (the estimator's "
     "fast path)"},
    {"imu_cycle", (PyCFunction)(void (*)(void))kernel_imu_cycle, METH_FASTCALL,
     "imu_cycle(consts, dims, spec, cols, bars, x, P, A, Q, x_out, P_out, A_out, out, work) -> "
     "status: one IMU sample's prediction step, prediction, measurements, update and "
     "projections (the estimator's fast path; nonzero: a stage refused, outputs unset)"},
    {"cycle_work", (PyCFunction)(void (*)(void))kernel_cycle_work, METH_FASTCALL,
     "cycle_work(dims, n) -> doubles of work imu_cycle() needs for an n-entry filter state"},
    {"use_blas", (PyCFunction)kernel_use_blas, METH_O,
     "use_blas(capsule): products through this dgemm (scipy.linalg.cython_blas's); None: the "
     "kernel's own loops"},
    {"jacobian_work", (PyCFunction)kernel_jacobian_work, METH_O,
     "jacobian_work(dims) -> doubles of work jacobian() needs"},
    {"imu_work", (PyCFunction)kernel_imu_work, METH_O,
     "imu_work(dims) -> doubles of work imu() needs"},
    {"rig_rhs", (PyCFunction)(void (*)(void))kernel_rig_rhs, METH_FASTCALL,
     "rig_rhs(consts, dims, x, u, out, work) -> 0: dx/dt of the rig-fidelity model"},
    {"rig_work", (PyCFunction)kernel_rig_work, METH_O,
     "rig_work(dims) -> doubles of work rig_rhs() needs"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_fastkernel",
                                    "Compiled kernel of gyrotensegrity.fast", -1, methods};

PyMODINIT_FUNC PyInit__fastkernel(void) {
    return PyModule_Create(&module);
}
