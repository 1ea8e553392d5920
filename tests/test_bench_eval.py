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


def test_op_count_follows_a_renamed_builtin_and_skips_integer_bit_work():
    """``#define log1p(x) brdfcl_log1p(x)``: a log1p in the kernel is the inline function, whose
    integer statements and bit-cast arguments are not flops."""
    source = """
inline real_v __attribute__((overloadable)) brdfcl_log1p(real_v x)
{
    const real_v u = 1 + x;
    const cond_v k = (as_cond_v(u) - 7) >> 23;
    const real_v m = as_real_v(k + (k << 23)) * 2;
    return m * u + x;
}
#define log1p(x) brdfcl_log1p(x)
__kernel void grad(KARGS)
{
    for (int v = v0 + lid; v < v1; v += 1) {
        acc += log1p(t);
    }
    /* work-group reduction */
}
"""
    ops, calls = bench_eval.op_count(source, "grad")
    assert ops == 1 + 4 and calls == {}       # v0 + lid; 1 + x, BITS * 2, m * u + x


OBJDUMP = """
0000000000003547 <_pocl_kernel_grad_workgroup_fast>:
    3547:\tpush   %r12
    3550:\tvmulps %zmm1,%zmm2,%zmm3
    3556:\tvfmadd213ps %zmm4,%zmm5,%zmm3
    355c:\tvmovups 0x40(%rsp),%zmm6
    3564:\tvaddps 0x80(%rsp),%zmm6,%zmm6
    356c:\tvpandd %zmm6,%zmm7,%zmm7
    3572:\tvmovups %zmm7,0x40(%rsp)
    357a:\tjne    3550 <_pocl_kernel_grad_workgroup_fast+0x9>
    3580:\tvdivps %zmm1,%zmm2,%zmm3
    3586:\tret
"""


def test_loop_mix_reads_the_hot_loop_of_the_disassembly():
    m = bench_eval.loop_mix(OBJDUMP, "grad")
    # the loop 3550..357a: 1 FMA, 2 one-flop (mul, add with a memory source), 1 other (pandd),
    # 2 pure moves to or from memory; the division after the loop is not in it
    assert (m["instructions"], m["fma"], m["arith"], m["other"], m["mem"]) == (7, 1, 2, 1, 2)
    assert m["flops"] == 4 and m["ceiling"] == 4 / (2 * 4)
    assert bench_eval.loop_mix(OBJDUMP, "jtj") is None


def test_no_instruction_mix_no_table():
    assert bench_eval.mix_lines([{"platform": "p", "kernel": "grad", "mix": None}]) == []
