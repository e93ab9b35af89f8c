
static void call_@NAME@(const V *const *x, V *out) { @STEM@_@NAME@_V(@ARGS@, out); }
static const int64_t size_@NAME@[] = {@SIZES@}, core_@NAME@[] = {@CORES@};
@NONZERO@
#if JAXSKID_PART == 0  /* the handlers: in the first part of a split build */
XLA_FFI_Error *jaxskid_@NAME@(XLA_FFI_CallFrame *call)
{
    return run(call, @N_IN@, size_@NAME@, core_@NAME@, @N_OUT@, @OUT_RANK@, call_@NAME@, @NZ@, @N_NZ@);
}
#endif
