/* The instantiation stage asks for the handler's API version; 1 then, 0 to execute. */
static int metadata(XLA_FFI_CallFrame *call)
{
    if (call->extension_start == NULL || call->extension_start->type != XLA_FFI_Extension_Metadata) return 0;
    XLA_FFI_Metadata *meta = ((XLA_FFI_Metadata_Extension *)call->extension_start)->metadata;
    meta->api_version.major_version = XLA_FFI_API_MAJOR;
    meta->api_version.minor_version = XLA_FFI_API_MINOR;
    meta->traits = 0;
    return 1;
}
