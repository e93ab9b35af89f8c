
static PyMethodDef methods[] = {
@ENTRIES@    {"configure", (PyCFunction)configure, METH_VARARGS, "configure(convert_arg, convert_params, defaults_complete)"},
    {NULL, NULL, 0, NULL}
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "@MODNAME@", NULL, -1, methods};

PyMODINIT_FUNC PyInit_@MODNAME@(void) {
    import_array();
    return PyModule_Create(&module);
}
