"""bench/bench_eval.py's operation count (the roofline's work per cell) on a small known source."""
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "bench"))
import bench_eval  # noqa: E402

SOURCE = """
/* helper: a / b + c * d */
inline real_v twice(real_v x, real a)
{
    return 2 * x / a;          // one *, one /
}
__kernel void grad(KARGS)
{
    const int v0 = 0;
    for (int v = v0 + lid; v < v1; v += 1) {
        const real_v t = twice(x, a) + twice(y, a);   /* + here: one op; * / in a comment: none */
        acc += sqrt(t) * log1p(t - 1.5e-3);
    }
    /* work-group reduction, then one partial per output */
    out[g * 2 + 1] = acc / 3;
}
"""


def test_op_count_expands_calls_skips_comments_and_counts_divisions_apart():
    ops, calls = bench_eval.op_count(SOURCE, "grad")
    # the header's v0 + lid; the body's +, -, * (+= is not counted) and twice() twice: 2 x (1 *),
    # divisions 2 x 1; the reduction after the loop, the comments and the exponent's sign are not
    assert ops == 1 + 3 + 2
    assert calls == {"div": 2, "sqrt": 1, "log1p": 1}


def test_flops_count_divider_operations_once_and_builtins_at_their_cost():
    """Division and square root one flop each (the divide unit overlaps the FMAs), a SLEEF builtin
    two flops per FMA time it measured."""
    assert bench_eval.flops_per_cell(10, {"div": 2, "sqrt": 1, "log1p": 1}, {"div": 4.0, "sqrt": 9.0, "log1p": 3.0}) \
        == 10 + 2 + 1 + 2 * 4
