
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include "@STEM@.h"

static PyObject *convert_arg = NULL;     /* (x, shape, what) -> C-contiguous float64 ndarray, or raises */
static PyObject *convert_params = NULL;  /* (params) -> C-contiguous float64 vector, or raises */
static int defaults_complete = 0;

/* ``x`` itself when it is a C-contiguous float64 array of shape ``dims``, else the converter's result; a new
   reference, or NULL with an exception set. */
static PyArrayObject *as_doubles(PyObject *x, int nd, const npy_intp *dims, const char *what) {
    if (PyArray_Check(x)) {
        PyArrayObject *a = (PyArrayObject *)x;
        if (PyArray_TYPE(a) == NPY_DOUBLE && PyArray_IS_C_CONTIGUOUS(a) && PyArray_NDIM(a) == nd) {
            int same = 1;
            for (int k = 0; k < nd; k++) same &= PyArray_DIM(a, k) == dims[k];
            if (same) { Py_INCREF(x); return a; }
        }
    }
    if (convert_arg == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "jaxskid native module used before configure()");
        return NULL;
    }
    PyObject *shape = PyTuple_New(nd);
    if (shape == NULL) return NULL;
    for (int k = 0; k < nd; k++) PyTuple_SET_ITEM(shape, k, PyLong_FromSsize_t(dims[k]));
    PyObject *out = PyObject_CallFunction(convert_arg, "OOs", x, shape, what);
    Py_DECREF(shape);
    if (out != NULL && !(PyArray_Check(out) && PyArray_TYPE((PyArrayObject *)out) == NPY_DOUBLE
                         && PyArray_IS_C_CONTIGUOUS((PyArrayObject *)out))) {
        Py_DECREF(out);
        PyErr_Format(PyExc_TypeError, "%s: the converter returned no float64 array", what);
        return NULL;
    }
    return (PyArrayObject *)out;
}

/* The parameter vector: the compiled defaults for None (``*held`` stays NULL), else an array held in
   ``*held``; NULL with an exception set on failure. */
static const double *param_pointer(PyObject *params, npy_intp n, PyArrayObject **held) {
    *held = NULL;
    if ((params == NULL || params == Py_None) && defaults_complete) return @STEM@_default_params;
    if (params != NULL && params != Py_None && PyArray_Check(params)) {
        PyArrayObject *a = (PyArrayObject *)params;
        if (PyArray_TYPE(a) == NPY_DOUBLE && PyArray_IS_C_CONTIGUOUS(a) && PyArray_NDIM(a) == 1
            && PyArray_DIM(a, 0) == n) {
            Py_INCREF(params);
            *held = a;
            return (const double *)PyArray_DATA(a);
        }
    }
    if (convert_params == NULL) {
        PyErr_SetString(PyExc_RuntimeError, "jaxskid native module used before configure()");
        return NULL;
    }
    PyObject *v = PyObject_CallOneArg(convert_params, params == NULL ? Py_None : params);
    if (v == NULL) return NULL;
    if (!(PyArray_Check(v) && PyArray_TYPE((PyArrayObject *)v) == NPY_DOUBLE
          && PyArray_IS_C_CONTIGUOUS((PyArrayObject *)v) && PyArray_SIZE((PyArrayObject *)v) == n)) {
        Py_DECREF(v);
        PyErr_SetString(PyExc_TypeError, "params: the converter returned no float64 vector of the right size");
        return NULL;
    }
    *held = (PyArrayObject *)v;
    return (const double *)PyArray_DATA(*held);
}

/* ``nstate`` positional state arguments, then ``params`` positionally or by keyword. */
static int split_args(PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames, Py_ssize_t nstate,
                      const char *name, PyObject **params) {
    Py_ssize_t nkw = kwnames == NULL ? 0 : PyTuple_GET_SIZE(kwnames);
    *params = NULL;
    if (nargs < nstate || nargs > nstate + 1) {
        PyErr_Format(PyExc_TypeError, "%s() takes %zd state arguments and params, got %zd positional",
                     name, nstate, nargs);
        return -1;
    }
    if (nargs == nstate + 1) *params = args[nstate];
    for (Py_ssize_t k = 0; k < nkw; k++) {
        PyObject *key = PyTuple_GET_ITEM(kwnames, k);
        if (!PyUnicode_Check(key) || PyUnicode_CompareWithASCIIString(key, "params") != 0 || *params != NULL) {
            PyErr_Format(PyExc_TypeError, "%s() got an unexpected keyword argument %R", name, key);
            return -1;
        }
        *params = args[nargs + k];
    }
    return 0;
}

static PyObject *configure(PyObject *self, PyObject *args) {
    PyObject *arg, *par;
    int complete;
    if (!PyArg_ParseTuple(args, "OOp", &arg, &par, &complete)) return NULL;
    Py_XINCREF(arg); Py_XSETREF(convert_arg, arg);
    Py_XINCREF(par); Py_XSETREF(convert_params, par);
    defaults_complete = complete;
    Py_RETURN_NONE;
}
