#if JAXSKID_PART == @OWNER@
PIECE void @NAME@(@PARAMS@)
@BODY@#else
PIECE void @NAME@(@PARAMS@);
#endif
