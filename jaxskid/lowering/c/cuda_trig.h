/* sin (quadrant 0) or cos (quadrant 1) in a CUDA kernel by multiply-adds (jaxskid/lowering/_cuda.py: TRIG), the
   method of jaxskid._fused and c/ffi_trig.h: x = n pi/2 + r, |r| <= pi/4 (Cody & Waite's three-part pi/2 by
   fused multiply-adds), then Cephes' minimax polynomials, chosen and signed by the quadrant. No branch: the
   angles' polynomials interleave, where the library's sin and cos each branch to a slow reduction. Within 2 ulp
   for |x| < 1e5; beyond, and for inf and nan, the library's sin and cos. */
JAXSKID_FN double jaxskid_trig(double x, long long quadrant)
{
    if (!(fabs(x) < 1e5)) /* beyond the exact reduction: the library's value, as the CPU kernels take libm's */
        return quadrant ? cos(x) : sin(x);
    const double n = rint(x * 0.63661977236758134308);
    double r = fma(-n, 1.57079632673412561417e+00, x);
    r = fma(-n, 6.07710050630396597660e-11, r);
    r = fma(-n, 2.02226624879595063154e-21, r);
    const double z = r * r;
    double ps = 1.58962301576546568060e-10;
    ps = ps * z + -2.50507477628578072866e-8;
    ps = ps * z + 2.75573136213857245213e-6;
    ps = ps * z + -1.98412698295895385996e-4;
    ps = ps * z + 8.33333333332211858878e-3;
    ps = ps * z + -1.66666666666666307295e-1;
    const double s = r + r * z * ps;
    double pc = -1.13585365213876817300e-11;
    pc = pc * z + 2.08757008419747316778e-9;
    pc = pc * z + -2.75573141792967388112e-7;
    pc = pc * z + 2.48015872888517045348e-5;
    pc = pc * z + -1.38888888888730564116e-3;
    pc = pc * z + 4.16666666666665929218e-2;
    const double c = 1.0 - 0.5 * z + z * z * pc;
    const long long k = (long long)n + quadrant;
    const double out = (k & 1) ? c : s;
    return (k & 2) ? -out : out;
}
#define Dsin(x) jaxskid_trig((x), 0)
#define Dcos(x) jaxskid_trig((x), 1)
