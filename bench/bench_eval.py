#!/usr/bin/env python3
"""Evaluation throughput: loss + gradient of a model over a MERL-proxy database.

Compares, in one run and on the same cells, the OpenCL kernels (float32 and
float64, all materials in one launch) with the float64 numpy reference and a
float32 numpy version (one material at a time), and places the kernels on a
roofline measured in the same run (a streaming-read kernel for bandwidth, an
FMA kernel for arithmetic).  Times are medians of --repeat runs; speed-ups are
ratios of throughputs (material-cells per second) measured side by side.

    python bench/bench_eval.py [--data DIR] [--model diffuse+diffraction+ggx]

It also compares, round-robin in the same run, every CPU runtime that builds here (the pip
wheel's PoCL, Debian's pocl-opencl-icd, Intel's OpenCL CPU runtime) at the width brdfcl chooses
and at the narrower safe widths; a runtime that cannot build on this CPU is named as left out.
"""
from __future__ import annotations

import argparse
import datetime
import json
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pyopencl as cl

from brdfcl import __version__
from brdfcl.data.geometry import table_geometry
from brdfcl.data.merl import list_database, read_merl
from brdfcl.device.engine import Engine, select_cells
from brdfcl.model.metrics import loss_grad

HERE = Path(__file__).resolve().parent
SHARED = HERE.parent.parent / "shared"


def proxy_dir(path):
    """The proxy database folder, generated from ../shared on first use."""
    path = Path(path)
    if not list(path.glob("*.binary")):
        tool = SHARED / "tools" / "merl_proxy.py"
        if not tool.exists():
            sys.exit(f"no .binary files in {path} and no {tool} to make them")
        print(f"generating the MERL-proxy database into {path} ...", flush=True)
        subprocess.run([sys.executable, str(tool), str(SHARED / "data" / "nbrdf" / "merl"), str(path)],
                       check=True, stdout=subprocess.DEVNULL)
    return path


def median_time(fn, repeat):
    fn()
    ts = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t)
    return float(np.median(ts))


TRANSCENDENTALS = ("exp", "log", "log1p", "sqrt", "erfc", "pow")
MEASURED = TRANSCENDENTALS + ("div",)    # operations timed against the FMA (a division is not one FMA slot)


def roof_source(vw, gpu=False):
    """Streaming-read, FMA-peak and per-builtin kernels in vectors of the engine's own width (a
    width the device's compiler may not target, such as 16 on a Zen 4 with the pip PoCL, fails
    to build).

    On a CPU the stream kernel reads one contiguous block per work-item (a CPU reads in cache
    lines; a GPU-style stride of the global size measured 4 GB/s against 35-64 GB/s); on a GPU
    (``gpu``) neighbouring work-items read neighbouring elements, stepping by the global size
    (coalesced: a block per work-item measured 447 GB/s on an H100).  The FMA kernel
    writes ``a * b + c`` (contracted to an FMA: the pip PoCL's ``fma()`` is an out-of-line call)
    on 8 independent chains, enough to hide the FMA latency.  Each builtin kernel runs the same
    8 chains through one builtin, so its time over the FMA kernel's is the builtin's cost in
    FMA-equivalents on this device and build (SLEEF's log1p is ~100 instructions, not one)."""
    v = f"float{vw}" if vw > 1 else "float"
    lanes = " + ".join(f"s.s{i:x}" for i in range(vw)) if vw > 1 else "s"
    chains = [f"x{i}" for i in range(8)]
    init = ", ".join(f"{x} = ({v})(g * 1e-7f + {0.3 + 0.05 * i}f)" for i, x in enumerate(chains))
    total = " + ".join(chains)

    def loop(step):
        return f"""    {v} {init};
    const {v} b = ({v})0.999f, c = ({v})1e-3f;
    for (int i = 0; i < iters; i++) {{
        {" ".join(step(x) for x in chains)}
    }}
    {v} s = {total};
    out[g] = {lanes};"""
    read = ("""    for (int i = g; i < n; i += ng) s0 += a[i];""" if gpu else
            """    const int per = (n + ng - 1) / ng, i0 = g * per, i1 = min(i0 + per, n);
    int i = i0;
    for (; i + 3 < i1; i += 4) { s0 += a[i]; s1 += a[i + 1]; s2 += a[i + 2]; s3 += a[i + 3]; }
    for (; i < i1; i++) s0 += a[i];""")
    src = f"""
__kernel void stream(__global const {v} *a, __global float *out, const int n) {{
    const int g = get_global_id(0), ng = get_global_size(0);
    {v} s0 = 0, s1 = 0, s2 = 0, s3 = 0;             /* 4 sums: no add-latency chain */
{read}
    {v} s = s0 + s1 + s2 + s3;
    out[g] = {lanes};
}}
__kernel void fma_peak(__global float *out, const int iters) {{
    const int g = get_global_id(0);
{loop(lambda x: f"{x} = {x} * b + c;")}
}}
"""
    arg = {"exp": "-{x}", "log": "{x} + 1.0f", "log1p": "{x}", "sqrt": "{x} + 0.5f", "erfc": "{x}",
           "pow": "{x} + 0.5f, b"}
    step = {fn: f"{{x}} = {fn}({a}) * b + c;" for fn, a in arg.items()}
    step["div"] = "{x} = b / ({x} + 2.0f) * b + c;"
    for fn in MEASURED:
        src += f"""__kernel void cost_{fn}(__global float *out, const int iters) {{
    const int g = get_global_id(0);
{loop(lambda x, fn=fn: step[fn].format(x=x))}
}}
"""
    return src


def roofline(eng, repeat):
    """(bandwidth B/s, FMA peak flop/s, {builtin: cost in FMA-equivalents}) of the engine's device."""
    ctx, queue, dev = eng.ctx, eng.queue, eng.device
    vw = eng.opt.vw
    gpu = bool(dev.type & cl.device_type.GPU)
    prg = cl.Program(ctx, roof_source(vw, gpu)).build()
    nv = (256 << 20) // (4 * vw)                             # 256 MiB of float vectors
    a = cl.Buffer(ctx, cl.mem_flags.READ_ONLY, nv * 4 * vw)
    cl.enqueue_fill_buffer(queue, a, np.float32(1), 0, nv * 4 * vw)
    nw = dev.max_compute_units * (2048 if gpu else 64)       # a GPU hides latency with many work-items
    out = cl.Buffer(ctx, cl.mem_flags.WRITE_ONLY, nw * 4)

    def timed(name, *args, best=False):
        k = cl.Kernel(prg, name)
        if best:                           # a peak is the best the device does: the fastest run
            return min(median_time(lambda: k(queue, (nw,), None, *args).wait(), 1) for _ in range(repeat))
        return median_time(lambda: k(queue, (nw,), None, *args).wait(), repeat)

    bw = nv * 4 * vw / timed("stream", a, out, np.int32(nv))
    iters = 4000 * 16 // vw
    t_fma = timed("fma_peak", out, np.int32(iters), best=True)
    flops = nw * iters * 8 * vw * 2 / t_fma
    cost = {fn: max(timed(f"cost_{fn}", out, np.int32(iters // 8)) * 8 / t_fma - 1.0, 0.0)
            for fn in MEASURED}
    return bw, flops, cost


def cpu_runtimes():
    """(flat device indices (brdfcl info) of every CPU device that builds programs here: each PoCL
    build, Intel's runtime; lines naming each CPU device left out and why)."""
    from brdfcl.device.buildcheck import label
    from brdfcl.device.platforms import is_cpu, usable
    found = usable(lambda p, d: is_cpu(d))
    return ([str(i) for i, p, d, c in found if c.ok],
            [f"{label(p)} left out: it cannot build a program on this CPU ({c.reason})." for i, p, d, c in found
             if not c.ok])


def is_pocl(dev) -> bool:
    from brdfcl.device.platforms import all_devices
    from brdfcl.device.platforms import is_pocl as pocl
    return pocl(all_devices()[int(dev)][0])


def runtime_name(eng) -> str:
    """The platform's version for a table row (``OpenCL 3.0 PoCL 3.1+debian``, ``OpenCL 3.1 LINUX
    (Intel(R) OpenCL)``)."""
    version = eng.device.platform.version.split("  ")[0]
    return version if "pocl" in version.lower() else f"{eng.device.platform.name} ({version})"


def sample_data(paths, n_mat):
    """(names, values (n, 3, cells) float64 at the fitted cells) of the first ``n_mat`` files: the
    materials of the per-kernel roofline and of the runtime comparison, read once for both."""
    from brdfcl.data.merl import MerlFile
    from brdfcl.device.engine import extract
    names, (data,) = extract([MerlFile(p) for p in paths[:n_mat]], [select_cells()], np.float64)
    return names, data


def compare(args, names, data):
    """Loss + gradient throughput of every CPU runtime that builds here at the width brdfcl chooses and at
    the narrower safe widths (8 floats, 4 doubles), measured round-robin in one run: each round
    times every configuration once, so machine noise hits them alike; medians over rounds.
    ``names``, ``data``: `sample_data`."""
    idx = select_cells()
    configs = []
    for dev in cpu_runtimes()[0]:
        for real, safe in (("float", 8), ("double", 4)):
            chosen = Engine(args.model, device=dev, real=real, metric=args.metric)
            for vw in sorted({chosen.opt.vw, safe}, reverse=True):
                eng = chosen if vw == chosen.opt.vw else Engine(args.model, device=dev, real=real,
                                                                metric=args.metric, vector_width=vw)
                configs.append({"device": dev, "platform": runtime_name(eng),
                                "real": real, "vw": vw, "chosen": vw == chosen.opt.vw, "eng": eng})
    for c in configs:
        c["cs"] = c["eng"].upload(names, idx, data.astype(c["eng"].dtype))
    V = np.tile(configs[0]["eng"].model.defaults(), (len(names), 1))
    mats = np.arange(len(names))
    times = {i: [] for i in range(len(configs))}
    for c in configs:                                         # warm-up: lazy kernel compiles
        c["eng"].grad(c["cs"], V, mats)
    for _ in range(args.repeat):
        for i, c in enumerate(configs):
            t = time.perf_counter()
            c["eng"].grad(c["cs"], V, mats)
            times[i].append(time.perf_counter() - t)
    for i, c in enumerate(configs):
        c["seconds"] = float(np.median(times[i]))
        c["rate"] = len(names) * idx.size / c["seconds"]
        del c["cs"], c["eng"]
    return configs, len(names)


def compare_lines(configs, n_mat, repeat):
    base = {c["real"]: c for c in configs if c["chosen"] and c["device"] == configs[0]["device"]}
    lines = ["## Vector widths and CPU runtimes, side by side", "",
             f"Loss + gradient of all {n_mat} materials in one launch, every configuration timed once per "
             f"round, {repeat} rounds, medians; ratios against the default device's chosen width "
             f"(`*`: the width brdfcl chooses on that device).", "",
             "| runtime | precision | vector width | time (s) | material-cells/s | relative throughput |",
             "|---|---|---|---|---|---|"]
    for c in configs:
        lines.append(f"| {c['platform']} | {c['real']} | {c['vw']}{' *' if c['chosen'] else ''} | "
                     f"{c['seconds']:.3f} | {c['rate']:.3g} | {c['rate'] / base[c['real']]['rate']:.2f} |")
    return lines


_OPS = re.compile(r"(?<![eE])[-+*](?!=)|\b(?:fmin|fmax)\b")
_DIV = re.compile(r"/(?!=)")
_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)
_TRANS = re.compile(r"\b(exp|log|log1p|sqrt|cbrt|erfc|pow)\s*\(")
_RENAME = re.compile(r"#define (\w+)\((\w+)\) (\w+)\(\2\)")          # log1p(x) -> brdfcl_log1p(x)
_FUNC = re.compile(r"inline \w+ (?:__attribute__\(\(\w+\)\) )?(\w+)\([^)]*\)\s*\{(.*?)\n\}", re.S)
_INT_STATEMENT = re.compile(r"^\s*(?:const\s+)?(?:int|long|cond_v)\d*\s[^;]*;", re.M)


def _without_bit_casts(text):
    """``text`` without the arguments of as_type() reinterpreting casts: integer arithmetic on a
    float's bits (exponent handling in brdfcl_log1p), not flops."""
    out, i = [], 0
    for m in re.finditer(r"\bas_\w+\(", text):
        if m.start() < i:
            continue
        out.append(text[i:m.start()])
        depth, j = 1, m.end()
        while depth:
            depth += {"(": 1, ")": -1}.get(text[j], 0)
            j += 1
        out.append("BITS")
        i = j
    return "".join(out) + text[i:]


def op_count(source, kernel="grad"):
    """(arithmetic ops, {builtin or 'div': calls}) per cell in a kernel's loop, from the generated
    source (comments removed).

    Inline functions are expanded once per call site, a builtin renamed by a ``#define`` (log1p)
    counted as the function it names; integer statements and the bits inside as_type() casts are
    not flops.  An estimate: compilers fold some operations and the transcendentals cost many
    instructions each."""
    for name, _, target in _RENAME.findall(source):
        source = re.sub(rf"\b{name}\s*\(", f"{target}(", _RENAME.sub("", source))
    body = source.split(f"void {kernel}(", 1)[1]
    body = _COMMENT.sub(" ", body.split("for (int v = v0", 1)[1].split("/* work-group reduction", 1)[0])
    funcs = {m.group(1): m.group(2) for m in _FUNC.finditer(_COMMENT.sub(" ", source))}

    def count(text, depth=0):
        text = _without_bit_casts(_INT_STATEMENT.sub("", text))
        text = re.sub(r"\[[^\]]*\]|\(size_t\)|\d+\.?\d*e[-+]\d+", "", text)
        ops = len(_OPS.findall(text))
        tr: dict = {"div": len(_DIV.findall(text))} if _DIV.search(text) else {}
        for fn in _TRANS.findall(text):
            tr[fn] = tr.get(fn, 0) + 1
        if depth < 3:
            for name, fbody in funcs.items():
                calls = len(re.findall(rf"\b{name}\s*\(", text))
                if calls:
                    o, inner = count(fbody, depth + 1)
                    ops += calls * o
                    for fn, k in inner.items():
                        tr[fn] = tr.get(fn, 0) + calls * k
        return ops, tr
    return count(body)


KERNELS = ("loss", "grad", "jtj")
CACHED = 160        # every 160th cell of one material: ~200 KB, the cache-resident timing
BYTES_PER_CELL = 9 * 4          # 6 geometry + 3 data floats per cell-evaluation (float32)


DIVIDER = ("div", "sqrt")     # run on the divide unit, beside the FMA units: one flop each, not FMA time


def flops_per_cell(ops, trans, cost):
    """A kernel's work per cell in flops: each arithmetic op one (a * b + c, an FMA, two), each
    division and square root one (they run on the divide unit beside the FMA units; timed alone they
    cost `cost` FMA slots, but in a kernel they overlap its FMAs), each other builtin (SLEEF: FMA
    arithmetic) two per FMA slot of its measured cost."""
    return ops + sum(k * (1 if fn in DIVIDER else 2 * (1 + cost.get(fn, 0.0))) for fn, k in trans.items())


def kernel_rooflines(args, names, data):
    """Per CPU runtime that builds here (the chosen device if none), float32 at the width brdfcl chooses: the
    device's roofline (`roofline`) and, for the loss, gradient and J^T J kernels over the materials
    ``names``, ``data`` (`sample_data`) in one launch, the work per cell (`op_count`,
    `flops_per_cell`), the achieved rate and its fraction of the roofline and of the FMA peak.
    Rows of dicts."""
    idx = select_cells()
    data = data.astype(np.float32)
    rows = []
    for dev in cpu_runtimes()[0] or [args.device]:
        eng = Engine(args.model, device=dev, real="float", metric=args.metric)
        cs = eng.upload(names, idx, data)
        V = np.tile(eng.model.defaults(), (len(names), 1))
        mats = np.arange(len(names))
        # the same work on every CACHED-th cell of one material (~200 KB: in cache), as many rows
        small = eng.upload(names[:1], idx[::CACHED], data[:1, :, ::CACHED])
        v_small = np.tile(eng.model.defaults(), (len(names) * CACHED, 1))
        m_small = np.zeros(len(names) * CACHED, dtype=np.int64)
        bw, peak, cost = roofline(eng, args.repeat)
        mixes = instruction_mix(args, dev, len(names)) if dev is not None and is_pocl(dev) else {}
        for kernel in KERNELS:
            run = getattr(eng, kernel)
            sec = median_time(lambda run=run: run(cs, V, mats), args.repeat)
            cells_small = len(names) * CACHED * idx[::CACHED].size
            in_cache = cells_small / median_time(lambda run=run: run(small, v_small, m_small), args.repeat)
            ops, trans = op_count(eng.source, kernel)
            work = flops_per_cell(ops, trans, cost)
            achieved = len(names) * idx.size / sec * work        # flop/s
            attainable = min(peak, work / BYTES_PER_CELL * bw)
            rows.append({"platform": runtime_name(eng), "vw": eng.opt.vw,
                         "kernel": kernel, "ops": ops, "trans": trans, "work": work, "seconds": sec,
                         "achieved": achieved, "attainable": attainable, "peak": peak,
                         "bandwidth": bw, "cost": cost, "mix": mixes.get(kernel),
                         "in_cache": in_cache / (len(names) * idx.size / sec)})
            rows[-1]["bound"] = "memory" if rows[-1]["in_cache"] > 1.15 else "compute"
    return rows, len(names)


def kernel_roofline_lines(rows, n_mat, repeat):
    lines = ["## Roofline per kernel and CPU runtime", "",
             f"float32, {n_mat} materials in one launch, medians of {repeat}; each device's bandwidth, FMA peak "
             "and builtin costs measured in the same run (`roofline`). Work per cell counted in the generated "
             "source (comments removed, inline functions expanded, dead code not removed: an upper estimate for "
             "the loss kernel, which computes derivatives it does not use), in flops: each +, -, *, fmin, fmax one; "
             "each division and square root one (the divide unit works beside the FMA units); each other builtin "
             "(SLEEF's FMA arithmetic) two per FMA of its measured cost. The FMA peak in flops (an FMA is two). "
             f"In-cache rate: cells per second of the same kernel on every {CACHED}th cell of one material (~200 KB, "
             "held in cache) over its rate on the full tables; bound: memory where the kernel runs more than 15% "
             "faster in cache, else compute (measured so: the streaming read of a shared machine moves from run to "
             "run, and with it the roofline's corner).", "",
             "| runtime | width | kernel | ops + calls per cell | flops per cell | achieved (GFLOP/s) | "
             "FMA peak (GFLOP/s) | of the roofline | of the FMA peak | in-cache rate | bound |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        calls = ", ".join(f"{k} {fn}" for fn, k in sorted(r["trans"].items()))
        lines.append(f"| {r['platform']} | {r['vw']} | {r['kernel']} | {r['ops']} ops, {calls} | {r['work']:.0f} | "
                     f"{r['achieved'] / 1e9:.1f} | {r['peak'] / 1e9:.1f} | "
                     f"{100 * r['achieved'] / r['attainable']:.0f}% | {100 * r['achieved'] / r['peak']:.0f}% | "
                     f"{r['in_cache']:.2f}x | {r['bound']} |")
    seen = {}
    for r in rows:
        seen.setdefault(r["platform"], r)
    lines.append("")
    for plat, r in seen.items():
        lines.append(f"* {plat}: streaming read {r['bandwidth'] / 1e9:.1f} GB/s; each operation timed alone, in FMA "
                     "times beyond the FMA: " + ", ".join(f"{fn} {c:.1f}" for fn, c in r["cost"].items()))
    return lines


_MIX_BUILD = """
import sys, numpy as np
from brdfcl.device.engine import Engine, select_cells
eng = Engine(sys.argv[1], real="float", metric=sys.argv[2])
idx = select_cells()
cs = eng.upload([f"m{i}" for i in range(int(sys.argv[3]))], idx, np.ones((int(sys.argv[3]), 3, idx.size), np.float32))
V = np.tile(eng.model.defaults(), (cs.n_materials, 1))
for k in sys.argv[4:]:
    getattr(eng, k)(cs, V, np.arange(cs.n_materials))
"""
_INSN = re.compile(r"\s+([0-9a-f]+):\t(\S+)\s*(.*)")
_FMA = ("vfmadd", "vfmsub", "vfnmadd", "vfnmsub")
_ONE_FLOP = ("vmulps", "vaddps", "vsubps", "vdivps", "vsqrtps", "vminps", "vmaxps")


def loop_mix(disassembly: str, kernel: str) -> dict | None:
    """The instruction mix of a PoCL kernel's hot loop (the longest backward jump of its
    ``_workgroup_fast`` function) from ``objdump -d``: FMAs, other arithmetic, other vector
    instructions that take a vector ALU port (integer bit work, compares, blends, register moves),
    pure loads and stores (register spills included); flops per cell as executed (an FMA two, every
    other arithmetic instruction one, per lane), and the ceiling of that mix: its flops if every
    vector ALU instruction took one slot of the FMA ports, as a fraction of the FMA peak."""
    fn = f"<_pocl_kernel_{kernel}_workgroup_fast>:"
    if fn not in disassembly:
        return None
    ins = [(int(m.group(1), 16), m.group(2), m.group(3)) for m in map(_INSN.match, disassembly.split(fn, 1)[1]
           .split("\n\n", 1)[0].splitlines()) if m]
    jumps = [(int(t.group(1), 16), a) for a, op, arg in ins if op.startswith("j")
             for t in [re.match(r"([0-9a-f]+) <", arg)] if t and int(t.group(1), 16) < a]
    if not jumps:
        return None
    lo, hi = max(jumps, key=lambda j: j[1] - j[0])
    loop = [(op, arg) for a, op, arg in ins if lo <= a <= hi]
    vec = [(op, arg) for op, arg in loop if op.startswith("v")]
    fma = sum(op.startswith(_FMA) for op, _ in vec)
    one = sum(op in _ONE_FLOP for op, _ in vec)
    mem = sum(op.startswith(("vmov", "vbroadcast")) and "(" in arg for op, arg in vec)
    alu = len(vec) - mem
    return {"instructions": len(loop), "fma": fma, "arith": one, "other": alu - fma - one, "mem": mem,
            "flops": 2 * fma + one, "ceiling": (2 * fma + one) / (2 * alu)}


def instruction_mix(args, dev: str, n_mat: int) -> dict:
    """{kernel: loop_mix} on one PoCL CPU device: its kernels built and run once in a child process
    with a PoCL cache of its own (the only place PoCL leaves the machine code), then disassembled.
    Empty where objdump or the machine code is missing (another OpenCL, another ISA)."""
    import os
    import shutil
    import subprocess
    import tempfile
    if not shutil.which("objdump"):
        return {}
    with tempfile.TemporaryDirectory() as cache:
        env = {**os.environ, "POCL_CACHE_DIR": cache, "BRDFCL_DEVICE": dev}
        if subprocess.run([sys.executable, "-c", _MIX_BUILD, args.model, args.metric, str(n_mat), *KERNELS],
                          env=env, capture_output=True).returncode != 0:
            return {}
        out = {}
        for kernel in KERNELS:
            for so in Path(cache).rglob(f"{kernel}.so"):
                asm = subprocess.run(["objdump", "-d", "--no-show-raw-insn", str(so)], capture_output=True,
                                     text=True).stdout
                mix = loop_mix(asm, kernel)
                if mix:
                    out[kernel] = mix
                    break
        return out


def mix_lines(rows) -> list[str]:
    """The instruction-mix table: per PoCL and kernel, beside the roofline rows' timings."""
    if not any(r.get("mix") for r in rows):
        return []
    lines = ["## Instruction mix of the hot loops", "",
             "The machine code PoCL built (`objdump -d` of its cached kernel, the loop of `_workgroup_fast`), one "
             "iteration = one vector of cells: FMA instructions, other arithmetic (multiply, add, subtract, divide, "
             "square root, min, max), other vector instructions on the ALU ports (integer bit work, compares, "
             "blends, register moves), pure loads and stores (spills included). Executed flops per cell: an FMA "
             "two, other arithmetic one. Ceiling: those flops if every vector ALU instruction took one FMA-port "
             "slot, as a fraction of the FMA peak (the best this mix can do: multiplies and adds that are not "
             "fused take a slot for one flop). Achieved: the executed flops at the roofline table's timing.", "",
             "| PoCL | kernel | instructions | FMA | other arithmetic | other vector ALU | loads + stores | "
             "executed flops per cell | ceiling of the mix | achieved, of the FMA peak |",
             "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        m = r.get("mix")
        if not m:
            continue
        rate = r["achieved"] / r["work"] * m["flops"]
        lines.append(f"| {r['platform']} | {r['kernel']} | {m['instructions']} | {m['fma']} | {m['arith']} | "
                     f"{m['other']} | {m['mem']} | {m['flops']:.0f} | {100 * m['ceiling']:.0f}% | "
                     f"{100 * rate / r['peak']:.0f}% |")
    return lines


def scattered_throughput(args, merl_rate, n_mat):
    """Loss + gradient on the real Cornell spectral measurement (31 bands, scattered samples, one
    geometry per material) next to the MERL tables, per sample-channel: n_mat copies of it in one
    launch, the model with one wavelength per band.  None when the measurement is absent."""
    from brdfcl.data.readers import read_samples
    from brdfcl.model.compose import Model
    from brdfcl.model.lobes.cells import Cells
    path = SHARED / "data" / "cornell" / "krylon_blue.brdf"
    if not path.exists():
        return None
    s = read_samples(path)
    ok = s.mask(80.0)
    cells = Cells.from_directions(s.wi[ok], s.wo[ok])
    model = Model(args.model, lambdas=tuple(s.wavelengths))
    eng = Engine(model, device=args.device, real="float", metric=args.metric)
    w, v = s.weights_within(80.0)[ok], s.values[ok].T
    cs = eng.upload_cells([f"{s.name}{i}" for i in range(n_mat)], [cells] * n_mat, [w] * n_mat, [v] * n_mat)
    V = np.tile(model.defaults(), (n_mat, 1))
    mats = np.arange(n_mat)
    eng.grad(cs, V, mats)
    sec = median_time(lambda: eng.grad(cs, V, mats), args.repeat)
    rate = n_mat * int(ok.sum()) * model.n_channels / sec
    return [f"Scattered spectral samples ({path.name}: {int(ok.sum())} samples x {model.n_channels} bands, "
            f"{model.n_free} free parameters, {n_mat} copies in one launch, float32): "
            f"{rate:.3g} material-sample-channels/s, {rate / merl_rate:.2f}x the MERL tables' "
            f"{merl_rate:.3g} material-cell-channels/s above (3 channels, {n_mat} materials)."]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", default=str(Path.home() / ".cache" / "brdfcl" / "proxy-all"),
                    help="folder of MERL(-proxy) .binary files (proxy generated there if empty)")
    ap.add_argument("--model", default="diffuse+diffraction+ggx")
    ap.add_argument("--metric", default="log")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--numpy-materials", type=int, default=2,
                    help="materials timed with numpy (it is slow; throughput is per material-cell)")
    ap.add_argument("--device", default=None)
    ap.add_argument("--compare-materials", type=int, default=24,
                    help="materials in the side-by-side comparison of widths and CPU runtimes (0: skip it)")
    ap.add_argument("--out", default=str(HERE / "results"))
    args = ap.parse_args(argv)

    data = proxy_dir(args.data)
    paths = list_database(data)
    idx = select_cells()
    rows, notes = [], {}

    t = time.perf_counter()
    eng32 = Engine(args.model, device=args.device, real="float", metric=args.metric)
    cs32 = eng32.cellset(read_merl(p) for p in paths)
    notes["load_s"] = time.perf_counter() - t
    n_mat, n_cells = cs32.n_materials, idx.size
    model = eng32.model
    V = np.tile(model.defaults(), (n_mat, 1))
    mats = np.arange(n_mat)
    t32 = median_time(lambda: eng32.grad(cs32, V, mats), args.repeat)
    rows.append(("OpenCL float32 (all materials, one launch)", n_mat, t32, n_mat * n_cells / t32))
    cs32 = None                                          # frees the device memory

    eng64 = Engine(args.model, device=args.device, real="double", metric=args.metric)
    cs64 = eng64.cellset(read_merl(p) for p in paths)
    t64 = median_time(lambda: eng64.grad(cs64, V, mats), args.repeat)
    rows.append(("OpenCL float64 (all materials, one launch)", n_mat, t64, n_mat * n_cells / t64))
    cs64 = None

    g = table_geometry()
    w = g.weight[idx]
    cells64 = eng64.cellset([], idx).cells()
    k = min(args.numpy_materials, n_mat)
    meas = [read_merl(p).brdf()[:, idx] for p in paths[:k]]
    for name, dt in (("numpy float64 reference", np.float64), ("numpy float32", np.float32)):
        cells = cells64.astype(dt)
        ms = [m.astype(dt) for m in meas]
        ww, cw = w.astype(dt), cells.ci

        def run():
            for m in ms:
                loss_grad(model, cells, m, ww, cw, V[0], args.metric)
        tn = median_time(run, max(1, args.repeat // 2))
        rows.append((f"{name} (one material at a time)", k, tn, k * n_cells / tn))

    ref = rows[2][3]
    lines = [f"# bench_eval: loss + gradient throughput ({datetime.date.today()})", "",
             f"Data: MERL-proxy ({n_mat} materials from {data}), {n_cells} cells per material "
             f"(80 degree cut-off). Model `{model.spec}` ({model.n_free} free parameters), metric "
             f"`{args.metric}`. Device: {eng32.device.name} ({eng32.device.platform.version}), "
             f"vector width {eng32.opt.vw} float / {eng64.opt.vw} double (chosen by brdfcl.device.width). "
             f"brdfcl {__version__}. Medians of {args.repeat} runs; numpy timed on {k} materials.", "",
             "| implementation | materials | time per evaluation of all of them (s) | "
             "material-cells/s | speed-up vs numpy float64 |", "|---|---|---|---|---|"]
    for name, nm, tt, rate in rows:
        lines.append(f"| {name} | {nm} | {tt:.3f} | {rate:.3g} | {rate / ref:.1f}x |")
    lines += ["", "The kernels on a roofline: the per-kernel table below (measured per CPU runtime, beside the "
              "kernels' own timings).", "",
              f"Database load (read 80 files, upload float32 cells): {notes['load_s']:.1f} s."]
    scattered = scattered_throughput(args, rows[0][3] * 3, n_mat)
    if scattered:
        lines += [""] + scattered
    sample = sample_data(paths, min(args.compare_materials or 24, n_mat))
    k_rows, n_k = kernel_rooflines(args, *sample)
    lines += [""] + kernel_roofline_lines(k_rows, n_k, args.repeat)
    mix = mix_lines(k_rows)
    lines += [""] + mix if mix else []
    cmp_rows = []
    runtimes, left_out = cpu_runtimes()
    if args.compare_materials and runtimes:
        cmp_rows, n_cmp = compare(args, *sample)
        lines += [""] + compare_lines(cmp_rows, n_cmp, args.repeat)
    elif args.compare_materials:
        lines += ["", "No CPU device builds here: the comparison of CPU runtimes and vector widths is left out."]
    lines += [""] + left_out if left_out else []
    text = "\n".join(lines)
    print(text)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench_eval.md").write_text(text + "\n")
    (out / "bench_eval.json").write_text(json.dumps({
        "rows": [dict(zip(("name", "materials", "seconds", "rate"), r)) for r in rows],
        "vector_width": eng32.opt.vw,
        "compare": cmp_rows, "kernels": k_rows}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
