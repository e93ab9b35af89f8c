#define PIECE __attribute__((noinline, visibility("hidden")))
