
/* sin (quadrant 0) or cos (quadrant 1) of every lane: x = n pi/2 + r with |r| <= pi/4 (Cody & Waite's
   three-part pi/2, exact products for |n| < 2^20), then the minimax polynomials of sin and cos on
   [-pi/4, pi/4] (the coefficients of Moshier's Cephes library), chosen and signed by the quadrant.
   Within 2 ulp of libm; lanes beyond 1e5 in magnitude, infinities and nan take libm's value. */
static inline @V@ @V@trig(@V@ x, long long quadrant)
{
    const @V@ shifter = @V@LIFT(6755399441055744.0); /* 1.5 * 2^52: adding it rounds to an integer */
    const @V@ n = (x * @V@LIFT(0.63661977236758134308) + shifter) - shifter;
    @V@ r = x - n * @V@LIFT(1.57079632673412561417e+00);
    r = r - n * @V@LIFT(6.07710050630396597660e-11);
    r = r - n * @V@LIFT(2.02226624879595063154e-21);
    const @V@ z = r * r;
    @V@ ps = @V@LIFT(1.58962301576546568060e-10);
    ps = ps * z + @V@LIFT(-2.50507477628578072866e-8);
    ps = ps * z + @V@LIFT(2.75573136213857245213e-6);
    ps = ps * z + @V@LIFT(-1.98412698295895385996e-4);
    ps = ps * z + @V@LIFT(8.33333333332211858878e-3);
    ps = ps * z + @V@LIFT(-1.66666666666666307295e-1);
    const @V@ s = r + r * z * ps;
    @V@ pc = @V@LIFT(-1.13585365213876817300e-11);
    pc = pc * z + @V@LIFT(2.08757008419747316778e-9);
    pc = pc * z + @V@LIFT(-2.75573141792967388112e-7);
    pc = pc * z + @V@LIFT(2.48015872888517045348e-5);
    pc = pc * z + @V@LIFT(-1.38888888888730564116e-3);
    pc = pc * z + @V@LIFT(4.16666666666665929218e-2);
    const @V@ c = @V@LIFT(1.0) - @V@LIFT(0.5) * z + z * z * pc;
    const @V@I k = __builtin_convertvector(n, @V@I) + quadrant;
    const @V@I odd = (k & 1) != 0, negative = (k & 2) != 0;
    const @V@I sign = (@V@I){0} + (long long)(1ULL << 63);
    @V@ out = (@V@)((((@V@I)c) & odd) | (((@V@I)s) & ~odd));
    out = (@V@)(((@V@I)out) ^ (negative & sign));
    for (int l = 0; l < (int)(sizeof(@V@) / sizeof(double)); l++)
        if (!(x[l] > -1e5 && x[l] < 1e5)) out[l] = quadrant ? cos(x[l]) : sin(x[l]);
    return out;
}

/* sign(x) of every lane, -1, 0 or 1 (the generated C's copysign((double)(x != 0), x); a comparison of vectors
   gives -1 where it holds) */
static inline @V@ @V@sign(@V@ x)
{
    return __builtin_convertvector((x < @V@LIFT(0.0)) - (x > @V@LIFT(0.0)), @V@);
}
