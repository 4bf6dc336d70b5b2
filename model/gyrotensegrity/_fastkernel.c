/* Compiled kernel of gyrotensegrity.fast (optional; the numpy path is the fallback).
 *
 * One function, rhs(consts, dims, x, u, out, work) -> status, evaluating the dense
 * formulation documented in fast.py for one state. All arrays are contiguous float64
 * buffers laid out by fast.py (_kernel_constants); dims is an int64 buffer
 * [m, beta, alpha, n_w, n_tq, c_u, diagonal]. Status 0 is success; k > 0 means the
 * constraint system lost positive definiteness at pivot k - 1 (singular geometry).
 * No Python objects are touched between argument parsing and return.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>

typedef struct {
    const double *EE_T, *off, *k_s, *c_s, *w2b, *tsel, *smask, *tgain, *WU, *Ef, *Minv,
        *MinvET, *EMinv, *Y, *Pu, *PuMinv, *X, *A3;
} Consts;

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

/* In-place Cholesky solve of the SPD system A s = b (A n x n, row-major). A pivot that
 * falls below PIVOT_RTOL times its diagonal entry (or is not finite) means the constraints
 * are dependent to working precision: the index of that row + 1 is returned. */
#define PIVOT_RTOL 1e-12
static int64_t cholesky_solve(double *A, double *b, int64_t n)
{
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
    return 0;
}

static int64_t evaluate(const Consts *k, const int64_t *d, const double *x, const double *u,
                        double *out, double *w)
{
    int64_t m = d[0], beta = d[1], alpha = d[2], nw = d[3], ntq = d[4], cu = d[5];
    int64_t diagonal = d[6], K = beta + alpha, nb = beta + 3 * cu;
    const double *q = x, *qd = x + 3 * m, *uw = u + alpha;
    double *pos = w, *vel = pos + 3 * K, *cols = vel + 3 * K, *f0 = cols + 3 * K;
    double *a = f0 + 3 * m, *b2 = a + 3 * m, *bd2 = b2 + beta, *gfac = bd2 + beta;
    double *omega = gfac + beta, *sol = omega + nw, *A = sol + nb;

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
    for (int64_t r = 0; r < 3; r++) {
        for (int64_t i = 0; i < m; i++) {
            double s = k->WU[r * m + i];
            for (int64_t j = 0; j < K; j++) s += cols[r * K + j] * k->Ef[j * m + i];
            f0[r * m + i] = s;
        }
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
                double bb = pos[i] * pos[j] + pos[K + i] * pos[K + j] +
                            pos[2 * K + i] * pos[2 * K + j];
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
    double *acc = out + 3 * m;
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

static PyObject *kernel_rhs(PyObject *self, PyObject *const *args, Py_ssize_t nargs)
{
    (void)self;
    if (nargs != 6) {
        PyErr_SetString(PyExc_TypeError, "rhs(consts, dims, x, u, out, work) takes 6 buffers");
        return NULL;
    }
    Py_buffer buf[6];
    int got = 0;
    for (; got < 6; got++) {
        int flags = (got >= 4) ? PyBUF_WRITABLE | PyBUF_C_CONTIGUOUS : PyBUF_C_CONTIGUOUS;
        if (PyObject_GetBuffer(args[got], &buf[got], flags) < 0) break;
    }
    int64_t status = -1;
    if (got == 6) {
        const int64_t *dims = (const int64_t *)buf[1].buf;
        Consts k;
        layout((const double *)buf[0].buf, dims, &k);
        Py_BEGIN_ALLOW_THREADS
        status = evaluate(&k, dims, (const double *)buf[2].buf, (const double *)buf[3].buf,
                          (double *)buf[4].buf, (double *)buf[5].buf);
        Py_END_ALLOW_THREADS
    }
    for (int i = 0; i < got; i++) PyBuffer_Release(&buf[i]);
    if (got != 6) return NULL;
    return PyLong_FromLongLong(status);
}

static PyMethodDef methods[] = {
    {"rhs", (PyCFunction)(void (*)(void))kernel_rhs, METH_FASTCALL,
     "rhs(consts, dims, x, u, out, work) -> status (0 ok, k > 0 singular at pivot k - 1)"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_fastkernel",
                                    "Compiled kernel of gyrotensegrity.fast", -1, methods};

PyMODINIT_FUNC PyInit__fastkernel(void) { return PyModule_Create(&module); }
