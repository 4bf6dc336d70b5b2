/* Compiled kernel of gyrotensegrity.fast (optional; the numpy path is the fallback).
 *
 * rhs(consts, dims, x, u, out, work) -> status evaluates the dense formulation documented
 * in fast.py for one state; jacobian(consts, dims, state, acc, J, work) -> status gives the
 * accelerations and their closed-form Jacobian (fast_jacobian.py, dense path without joints). All
 * arrays are contiguous float64 buffers laid out by fast.py (_kernel_constants); dims is an int64
 * buffer [m, beta, alpha, n_w, n_tq, c_u, diagonal]. Status 0 is success; k > 0 means the
 * constraint system lost positive definiteness at pivot k - 1 (singular geometry).
 * No Python objects are touched between argument parsing and return.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>

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

/* b <- A^-1 b with A's Cholesky factor L (lower triangle of A): forward, then backward. */
static void cholesky_subst(const double* A, double* b, int64_t n) {
    for (int64_t i = 0; i < n; i++) {
        double s = b[i];
        for (int64_t k = 0; k < i; k++) s -= A[i * n + k] * b[k];
        b[i] = s / A[i * n + i];
    }
    for (int64_t i = n - 1; i >= 0; i--) {
        double s = b[i];
        for (int64_t k = i + 1; k < n; k++) s -= A[k * n + i] * b[k];
        b[i] = s / A[i * n + i];
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
    return 27 * K + 3 * m + 11 * beta + 3 * alpha + beta * beta + beta * m + (3 * m + beta) * D;
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

/* Accelerations (3, m) and their Jacobian (3 m x D) at state [q, q_dot, omega_w, rest] for
 * the dense path without joints (fast_jacobian.py: the derivation). Status as evaluate(). */
static int64_t jacobian(const Consts* k, const int64_t* d, const double* x, double* acc, double* J,
                        double* w) {
    int64_t m = d[0], beta = d[1], alpha = d[2], nw = d[3];
    int64_t K = beta + alpha, D = 6 * m + nw + alpha;
    const double *q = x, *qd = x + 3 * m, *om = x + 6 * m, *rest = x + 6 * m + nw;
    double *pos = w, *vel = pos + 3 * K, *cols = vel + 3 * K, *Dq = cols + 3 * K;
    double *Dd = Dq + 9 * K, *f0 = Dd + 9 * K, *V = f0 + 3 * m, *gxb = V + 3 * beta;
    double *Dr = gxb + 3 * beta, *mu = Dr + 3 * alpha, *tmp = mu + beta, *Z = tmp + beta;
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
                for (int64_t c = 0; c < D; c++) row[c] += g * src[c];
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
                for (int64_t c = 0; c < D; c++) row[c] += g * src[c];
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
    for (int64_t c = 0; c < D; c++) {
        for (int64_t j = 0; j < beta; j++) tmp[j] = Jr[j * D + c];
        cholesky_subst(Z, tmp, beta);
        for (int64_t j = 0; j < beta; j++) Jr[j * D + c] = tmp[j];
    }
    /* z_ddot = a0 + (B mu^) E M^-1 */
    for (int64_t r = 0; r < 3; r++) {
        for (int64_t j = 0; j < m; j++) {
            double* row = J + (r * m + j) * D;
            for (int64_t i = 0; i < beta; i++) {
                double g = pos[r * K + i] * k->EMinv[i * m + j];
                acc[r * m + j] += mu[i] * g;
                const double* src = Jr + i * D;
                for (int64_t c = 0; c < D; c++) row[c] += g * src[c];
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

/* The six buffers of a call: the first four read, the last two written. */
static int get_buffers(PyObject* const* args, Py_ssize_t nargs, Py_buffer* buf, const char* use) {
    if (nargs != 6) {
        PyErr_SetString(PyExc_TypeError, use);
        return -1;
    }
    int got = 0;
    for (; got < 6; got++) {
        int flags = (got >= 4) ? PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS : PyBUF_C_CONTIGUOUS;
        if (PyObject_GetBuffer(args[got], &buf[got], flags) < 0) break;
    }
    if (got == 6) return 0;
    for (int i = 0; i < got; i++) PyBuffer_Release(&buf[i]);
    return -1;
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

static PyObject* kernel_jacobian_work(PyObject* self, PyObject* arg) {
    (void)self;
    Py_buffer dims;
    if (PyObject_GetBuffer(arg, &dims, PyBUF_C_CONTIGUOUS) < 0) return NULL;
    int64_t n = jacobian_work((const int64_t*)dims.buf);
    PyBuffer_Release(&dims);
    return PyLong_FromLongLong(n);
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
    {"jacobian_work", (PyCFunction)kernel_jacobian_work, METH_O,
     "jacobian_work(dims) -> doubles of work jacobian() needs"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_fastkernel",
                                    "Compiled kernel of gyrotensegrity.fast", -1, methods};

PyMODINIT_FUNC PyInit__fastkernel(void) {
    return PyModule_Create(&module);
}
