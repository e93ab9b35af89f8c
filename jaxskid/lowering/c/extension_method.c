
static PyObject *m_@NAME@(PyObject *self, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames) {
    PyObject *params, *out = NULL;
    PyArrayObject *a[@NSTATE@] = {NULL}, *held = NULL;
    const double *p;
@DIMS@    if (split_args(args, nargs, kwnames, @NSTATE@, "@NAME@", &params) < 0) return NULL;
@LOADS@    p = param_pointer(params, @N_PARAMS@, &held);
    if (p == NULL) goto done;
    {
        npy_intp od[@OUT_ALLOC@] = {@OUT_DIMS@};
        out = PyArray_SimpleNew(@OUT_ND@, od, NPY_DOUBLE);
    }
    if (out == NULL) goto done;
    @C_NAME@(@POINTERS@p, (double *)PyArray_DATA((PyArrayObject *)out));
done:
    for (int k = 0; k < @NSTATE@; k++) Py_XDECREF(a[k]);
    Py_XDECREF(held);
    return out;
}
