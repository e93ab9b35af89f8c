/* lambda = M^-1 g by M = L D L^T (Golub & Van Loan, Alg. 4.1.2; a pivot <= 0 gives nan), then the
   vector-Jacobian product of inverse dynamics at lambda, negated. out = [lambda (N), -vjp (NV)]. */
static void backward(const T *q, const T *qd, const T *a, const T *g, const T *p, T *out)
{
    T m[N * N], d[N], y[N];
    MASS(q, p, m);
    for (int j = 0; j < N; j++) {
        T s = m[j * N + j];
        for (int k = 0; k < j; k++) s -= m[j * N + k] * m[j * N + k] * d[k];
        d[j] = positive_or_nan(s);
        for (int i = j + 1; i < N; i++) {
            T t = m[i * N + j];
            for (int k = 0; k < j; k++) t -= m[i * N + k] * m[j * N + k] * d[k];
            m[i * N + j] = t / d[j];
        }
    }
    for (int i = 0; i < N; i++) {
        T s = g[i];
        for (int k = 0; k < i; k++) s -= m[i * N + k] * y[k];
        y[i] = s;
    }
    for (int i = N - 1; i >= 0; i--) {
        T s = y[i] / d[i];
        for (int k = i + 1; k < N; k++) s -= m[k * N + i] * out[k];
        out[i] = s;
    }
    VJP(q, qd, a, out, p, out + N);
    for (int i = N; i < NO; i++) out[i] = -out[i];
}
