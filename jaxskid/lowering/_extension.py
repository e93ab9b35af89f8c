"""The ``"capi"`` backend of :mod:`._native`: the generated C wrapped in a CPython extension module of its
own, one method per quantity, called with no layer in between.

cffi and ctypes cost a few hundred nanoseconds a call in their own machinery (a buffer view per argument, a
foreign-function call); for a 3-DOF robot that is most of a call. Here each quantity is a ``METH_FASTCALL``
function of the module: it checks every argument with NumPy's C API (a C-contiguous float64 array of the
expected shape is used in place), allocates the result with ``PyArray_SimpleNew`` and calls the generated C
directly. Anything else (a list, float32, a strided view, a dict of parameters, a wrong shape) goes to Python
converters that the module is given once (:func:`configure`), so conversions and error messages are those
of the other backends.

Calling convention of every method: ``name(*state, params=None)``; ``params`` may be passed by keyword;
``None`` takes the default vector compiled into the C (``<stem>_default_params``) when every default is
known, else the converter reports the missing ones.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass


@dataclass(frozen=True)
class Method:
    """One method of the extension: the Python name, the generated C function, the state arguments with their
    shapes, the number of parameters, the result's shape and the docstring."""

    name: str
    c_name: str
    args: tuple[tuple[str, tuple[int, ...]], ...]
    n_params: int
    out_shape: tuple[int, ...]
    doc: str


_PRELUDE = r"""
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#define NPY_NO_DEPRECATED_API NPY_1_7_API_VERSION
#include <numpy/arrayobject.h>
#include "{stem}.h"

static PyObject *convert_arg = NULL;     /* (x, shape, what) -> C-contiguous float64 ndarray, or raises */
static PyObject *convert_params = NULL;  /* (params) -> C-contiguous float64 vector, or raises */
static int defaults_complete = 0;

/* ``x`` itself when it is a C-contiguous float64 array of shape ``dims``, else the converter's result; a new
   reference, or NULL with an exception set. */
static PyArrayObject *as_doubles(PyObject *x, int nd, const npy_intp *dims, const char *what) {{
    if (PyArray_Check(x)) {{
        PyArrayObject *a = (PyArrayObject *)x;
        if (PyArray_TYPE(a) == NPY_DOUBLE && PyArray_IS_C_CONTIGUOUS(a) && PyArray_NDIM(a) == nd) {{
            int same = 1;
            for (int k = 0; k < nd; k++) same &= PyArray_DIM(a, k) == dims[k];
            if (same) {{ Py_INCREF(x); return a; }}
        }}
    }}
    if (convert_arg == NULL) {{
        PyErr_SetString(PyExc_RuntimeError, "jaxskid native module used before configure()");
        return NULL;
    }}
    PyObject *shape = PyTuple_New(nd);
    if (shape == NULL) return NULL;
    for (int k = 0; k < nd; k++) PyTuple_SET_ITEM(shape, k, PyLong_FromSsize_t(dims[k]));
    PyObject *out = PyObject_CallFunction(convert_arg, "OOs", x, shape, what);
    Py_DECREF(shape);
    if (out != NULL && !(PyArray_Check(out) && PyArray_TYPE((PyArrayObject *)out) == NPY_DOUBLE
                         && PyArray_IS_C_CONTIGUOUS((PyArrayObject *)out))) {{
        Py_DECREF(out);
        PyErr_Format(PyExc_TypeError, "%s: the converter returned no float64 array", what);
        return NULL;
    }}
    return (PyArrayObject *)out;
}}

/* The parameter vector: the compiled defaults for None (``*held`` stays NULL), else an array held in
   ``*held``; NULL with an exception set on failure. */
static const double *param_pointer(PyObject *params, npy_intp n, PyArrayObject **held) {{
    *held = NULL;
    if ((params == NULL || params == Py_None) && defaults_complete) return {stem}_default_params;
    if (params != NULL && params != Py_None && PyArray_Check(params)) {{
        PyArrayObject *a = (PyArrayObject *)params;
        if (PyArray_TYPE(a) == NPY_DOUBLE && PyArray_IS_C_CONTIGUOUS(a) && PyArray_NDIM(a) == 1
            && PyArray_DIM(a, 0) == n) {{
            Py_INCREF(params);
            *held = a;
            return (const double *)PyArray_DATA(a);
        }}
    }}
    if (convert_params == NULL) {{
        PyErr_SetString(PyExc_RuntimeError, "jaxskid native module used before configure()");
        return NULL;
    }}
    PyObject *v = PyObject_CallOneArg(convert_params, params == NULL ? Py_None : params);
    if (v == NULL) return NULL;
    if (!(PyArray_Check(v) && PyArray_TYPE((PyArrayObject *)v) == NPY_DOUBLE
          && PyArray_IS_C_CONTIGUOUS((PyArrayObject *)v) && PyArray_SIZE((PyArrayObject *)v) == n)) {{
        Py_DECREF(v);
        PyErr_SetString(PyExc_TypeError, "params: the converter returned no float64 vector of the right size");
        return NULL;
    }}
    *held = (PyArrayObject *)v;
    return (const double *)PyArray_DATA(*held);
}}

/* ``nstate`` positional state arguments, then ``params`` positionally or by keyword. */
static int split_args(PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames, Py_ssize_t nstate,
                      const char *name, PyObject **params) {{
    Py_ssize_t nkw = kwnames == NULL ? 0 : PyTuple_GET_SIZE(kwnames);
    *params = NULL;
    if (nargs < nstate || nargs > nstate + 1) {{
        PyErr_Format(PyExc_TypeError, "%s() takes %zd state arguments and params, got %zd positional",
                     name, nstate, nargs);
        return -1;
    }}
    if (nargs == nstate + 1) *params = args[nstate];
    for (Py_ssize_t k = 0; k < nkw; k++) {{
        PyObject *key = PyTuple_GET_ITEM(kwnames, k);
        if (!PyUnicode_Check(key) || PyUnicode_CompareWithASCIIString(key, "params") != 0 || *params != NULL) {{
            PyErr_Format(PyExc_TypeError, "%s() got an unexpected keyword argument %R", name, key);
            return -1;
        }}
        *params = args[nargs + k];
    }}
    return 0;
}}

static PyObject *configure(PyObject *self, PyObject *args) {{
    PyObject *arg, *par;
    int complete;
    if (!PyArg_ParseTuple(args, "OOp", &arg, &par, &complete)) return NULL;
    Py_XINCREF(arg); Py_XSETREF(convert_arg, arg);
    Py_XINCREF(par); Py_XSETREF(convert_params, par);
    defaults_complete = complete;
    Py_RETURN_NONE;
}}
"""

_METHOD = r"""
static PyObject *m_{name}(PyObject *self, PyObject *const *args, Py_ssize_t nargs, PyObject *kwnames) {{
    PyObject *params, *out = NULL;
    PyArrayObject *a[{nstate}] = {{NULL}}, *held = NULL;
    const double *p;
{dims}    if (split_args(args, nargs, kwnames, {nstate}, "{name}", &params) < 0) return NULL;
{loads}    p = param_pointer(params, {n_params}, &held);
    if (p == NULL) goto done;
    {{
        npy_intp od[{out_alloc}] = {{{out_dims}}};
        out = PyArray_SimpleNew({out_nd}, od, NPY_DOUBLE);
    }}
    if (out == NULL) goto done;
    {c_name}({pointers}p, (double *)PyArray_DATA((PyArrayObject *)out));
done:
    for (int k = 0; k < {nstate}; k++) Py_XDECREF(a[k]);
    Py_XDECREF(held);
    return out;
}}
"""

_MODULE = r"""
static PyMethodDef methods[] = {{
{entries}    {{"configure", (PyCFunction)configure, METH_VARARGS, "configure(convert_arg, convert_params, defaults_complete)"}},
    {{NULL, NULL, 0, NULL}}
}};

static struct PyModuleDef module = {{PyModuleDef_HEAD_INIT, "{modname}", NULL, -1, methods}};

PyMODINIT_FUNC PyInit_{modname}(void) {{
    import_array();
    return PyModule_Create(&module);
}}
"""


def _c_string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n") + '"'


def _method(m: Method) -> str:
    dims = "".join(f"    static const npy_intp d{k}[{max(len(s), 1)}] = {{{', '.join(map(str, s)) or '0'}}};\n"
                   for k, (_, s) in enumerate(m.args))
    loads = "".join(
        f"    a[{k}] = as_doubles(args[{k}], {len(s)}, d{k}, \"{m.name}: {a}\");\n    if (a[{k}] == NULL) goto done;\n"
        for k, (a, s) in enumerate(m.args))
    pointers = "".join(f"(const double *)PyArray_DATA(a[{k}]), " for k in range(len(m.args)))
    out_dims = ", ".join(map(str, m.out_shape)) or "1"
    return _METHOD.format(name=m.name, nstate=max(len(m.args), 1), dims=dims, loads=loads, n_params=m.n_params,
                          out_nd=len(m.out_shape), out_alloc=max(len(m.out_shape), 1), out_dims=out_dims, c_name=m.c_name, pointers=pointers)


def extension_source(stem: str, modname: str, methods: Sequence[Method]) -> str:
    """The C of the extension module ``modname`` around ``<stem>.h``: one function per :class:`Method`."""
    entries = "".join(
        f"    {{\"{m.name}\", (PyCFunction)(void (*)(void))m_{m.name}, METH_FASTCALL | METH_KEYWORDS, "
        f"{_c_string(m.doc)}}},\n" for m in methods)
    return (_PRELUDE.format(stem=stem) + "".join(_method(m) for m in methods)
            + _MODULE.format(entries=entries, modname=modname))
