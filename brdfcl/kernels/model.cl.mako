/* brdfcl model kernels, generated for: ${spec}
 * real = ${real}, vector width ${vw}, metric ${metric}, cos(theta_i) weight ${'on' if cosw else 'off'}.
 *
 * Work layout: dimension 0 = evaluation (a parameter vector for one material), dimension 1 =
 * chunks of cells; a work-group of ${wg} items strides over ${chunk} vectors of ${vw} cells,
 * accumulates in private vectors, reduces in local memory and writes one partial sum per
 * output; the host adds the partials in float64 (bounded float accumulation, exact total).
 * Channels: ${'one loop over the ' + str(n_ch) + ' channels' if ch_loop else 'written out one by one'}. */
% if real == "double":
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
% endif
typedef ${real} real;
typedef ${real_v} real_v;
typedef ${cond_v} cond_v;
% if vw == 1:
#define VLOAD(p, o) ((p)[o])
% else:
/* an aligned vector load (o is a multiple of the width, rows are padded to it): vload is an
 * out-of-line call in the pip PoCL */
#define VLOAD(p, o) (*(__global const real_v *)((p) + (o)))
% endif

${common}
% if real == "float":

/* log1p, log and exp written inline (brdfcl/kernels/inline_math.py): SLEEF's are divisions and
 * double-float arithmetic, and out-of-line calls in the pip PoCL */
% for src in inline_math:
${src}
% endfor
% for name in inline_names:
#undef ${name}
#define ${name}(x) brdfcl_${name}(x)
% endfor
% endif

% for src in sources:
${src}
% endfor
% if ch_loop:

/* each channel's numbers (Known.k) and J^T J entries, read in the loop over channels */
% for name, ctype, vals in tables:
__constant ${ctype} ${name}[${len(vals)}] = {${', '.join(('(real)%r' % v) if ctype == 'real' else str(v) for v in vals)}};
% endfor
% endif

/* metric (brdfcl/metrics.py) */
inline real_v metric_g(real_v x)
{
    return ${metric_g};
}

inline real_v metric_dg(real_v x, real_v g)
{
    return ${metric_dg};
}

inline real hsum(real_v v)
{
% if vw == 1:
    return v;
% else:
<% w = vw %>\
% while w > 1:
<% w //= 2 %>\
    ${'real' if w == 1 else real + str(w)} h${w} = ${'v' if w * 2 == vw else 'h' + str(w * 2)}.lo + ${'v' if w * 2 == vw else 'h' + str(w * 2)}.hi;
% endwhile
    return h1;
% endif
}

<%def name="prologue()">
    const int e = get_global_id(0);
    const int g = get_group_id(1), ng = get_num_groups(1);
    const int lid = get_local_id(1);
    __global const real *P = prm + (size_t)e * ${n_prm};
% for s in slots:
% if not (ch_loop and s.channel is not None):
    const real ${s.cname} = P[${loop.index}];
% endif
% endfor
% for k in consts:
    const real ${k} = P[${n_slots + loop.index}];
% endfor
    __global const real *M = data + (size_t)mat[e] * ${n_ch} * n_cells;
    __global const real *G = geom + (size_t)(mat[e] + mat0) * geo_stride;    /* 0: one geometry for all */
    const int v0 = g * ${chunk}, v1 = min(v0 + ${chunk}, n_cells / ${vw});
</%def>

<%def name="cell_and_model()">
        const int o = v * ${vw};
        cell_t c = make_cell(VLOAD(G, o), VLOAD(G, n_cells + o), VLOAD(G, 2 * n_cells + o),
                             VLOAD(G, 3 * n_cells + o), VLOAD(G, 4 * n_cells + o));
        const real_v w = VLOAD(G, 5 * n_cells + o);
% if ch_loop:
% for line in loop_lines:
        ${line}
% endfor
% else:
% for line in lines:
        ${line}
% endfor
% for ch in range(n_ch):
        const real_v p${ch} = ${' + '.join(value[ch]) if value[ch] else '(real_v)0'};
% endfor
% endif
</%def>

<%def name="channel_model()">
% for name, pos in loads:
            const real ${name} = P[${pos} + ch];
% endfor
% for line in body:
            ${line}
% endfor
            const real_v p = ${' + '.join(loop_value) if loop_value else '(real_v)0'};
</%def>

<%def name="channel_residual()">
            const real_v t = VLOAD(M, ch * n_cells + o);     /* g(m cw), from the target kernel */
            const real_v x = p * cw;
            const real_v gx = metric_g(x);
            const real_v wc = SEL(w, (real_v)0, t != t);   /* NaN: a missing cell */
            const real_v r = SEL(gx - t, (real_v)0, t != t);
</%def>

<%def name="arrays(n_g, n_h)">
    real_v acc_l = 0;
    real_v acc_g[${max(n_g, 1)}], acc_h[${max(n_h, 1)}];
    for (int k = 0; k < ${max(n_g, 1)}; k++) acc_g[k] = 0;
    for (int k = 0; k < ${max(n_h, 1)}; k++) acc_h[k] = 0;
</%def>

<%def name="residuals()">
        const real_v cw = ${'c.ci' if cosw else '(real_v)1'};
% for ch in range(n_ch):
        const real_v t${ch} = VLOAD(M, ${ch} * n_cells + o);     /* g(m cw), from the target kernel */
        const real_v x${ch} = p${ch} * cw;
        const real_v g${ch} = metric_g(x${ch});
        const real_v w${ch} = SEL(w, (real_v)0, t${ch} != t${ch});   /* NaN: a missing cell */
        const real_v r${ch} = SEL(g${ch} - t${ch}, (real_v)0, t${ch} != t${ch});
% endfor
</%def>

<%def name="reduce_one(a, index)">
    red[lid] = hsum(${a});
% if wg > 1:
    barrier(CLK_LOCAL_MEM_FENCE);
    for (int s = ${wg} / 2; s > 0; s >>= 1) {
        if (lid < s) red[lid] += red[lid + s];
        barrier(CLK_LOCAL_MEM_FENCE);
    }
% endif
    if (lid == 0) out_e[${index}] = red[0];
% if wg > 1:
    barrier(CLK_LOCAL_MEM_FENCE);
% endif
</%def>

<%def name="reduce_and_write(names, arrays=())">
    /* work-group reduction, then one partial per output */
    __local real red[${wg}];
    __global real *out_e = out + ((size_t)e * ng + g) * ${len(names) + sum(n for _, n in arrays)};
% for a in names:
${reduce_one(a, loop.index)}
% endfor
<% at = len(names) %>\
% for a, n in arrays:
    for (int k = 0; k < ${n}; k++) {
${reduce_one(a + '[k]', str(at) + ' + k')}
    }
<% at += n %>\
% endfor
</%def>

#define KARGS __global const real *geom, const int n_cells, const int geo_stride, const int mat0, \
              __global const real *data, \
              __global const real *prm, __global const int *mat, __global real *out

/* the fit's target g(m cw) of every measured value, once per upload (data: the measured values;
 * out: the targets, in the same layout; NaN stays NaN).  loss, grad and jtj read these targets as
 * their data, so that the metric of the data is not recomputed at every evaluation. */
__kernel __attribute__((reqd_work_group_size(1, ${wg}, 1))) void target(KARGS)
{
    const int e = get_global_id(0);
    const int g = get_group_id(1);
    const int lid = get_local_id(1);
    __global const real *M = data + (size_t)mat[e] * ${n_ch} * n_cells;
    __global const real *G = geom + (size_t)(mat[e] + mat0) * geo_stride;
    __global real *T = out + (size_t)mat[e] * ${n_ch} * n_cells;
    const int v0 = g * ${chunk}, v1 = min(v0 + ${chunk}, n_cells / ${vw});
    for (int v = v0 + lid; v < v1; v += ${wg}) {
        const int o = v * ${vw};
        const real_v cw = ${'VLOAD(G, 3 * n_cells + o)' if cosw else '(real_v)1'};
% if ch_loop:
        for (int ch = 0; ch < ${n_ch}; ch++)
            *(__global real_v *)(T + ch * n_cells + o) = metric_g(VLOAD(M, ch * n_cells + o) * cw);
% else:
% for ch in range(n_ch):
        *(__global real_v *)(T + ${ch} * n_cells + o) = metric_g(VLOAD(M, ${ch} * n_cells + o) * cw);
% endfor
% endif
    }
}

/* loss = sum w r^2 */
__kernel __attribute__((reqd_work_group_size(1, ${wg}, 1))) void loss(KARGS)
{
${prologue()}
    real_v acc_l = 0;
    for (int v = v0 + lid; v < v1; v += ${wg}) {
${cell_and_model()}
% if ch_loop:
        const real_v cw = ${'c.ci' if cosw else '(real_v)1'};
        for (int ch = 0; ch < ${n_ch}; ch++) {
${channel_model()}
${channel_residual()}
            acc_l += wc * r * r;
        }
% else:
${residuals()}
% for ch in range(n_ch):
        acc_l += w${ch} * r${ch} * r${ch};
% endfor
% endif
    }
${reduce_and_write(['acc_l'])}
}

/* loss and J^T W r (the gradient is 2 J^T W r) */
__kernel __attribute__((reqd_work_group_size(1, ${wg}, 1))) void grad(KARGS)
{
${prologue()}
% if ch_loop:
${arrays(n_free, 0)}
% else:
    real_v acc_l = 0;
% for k in range(n_free):
    real_v acc_g${k} = 0;
% endfor
% endif
    for (int v = v0 + lid; v < v1; v += ${wg}) {
${cell_and_model()}
% if ch_loop:
        const real_v cw = ${'c.ci' if cosw else '(real_v)1'};
        for (int ch = 0; ch < ${n_ch}; ch++) {
${channel_model()}
${channel_residual()}
            acc_l += wc * r * r;
            const real_v q = wc * r * metric_dg(x, gx) * cw;
% for i, col, parts in loop_jac:
            acc_g[${col}] += q * (${' + '.join(parts)});
% endfor
        }
% else:
${residuals()}
% for ch in range(n_ch):
        {
        acc_l += w${ch} * r${ch} * r${ch};
        const real_v q = w${ch} * r${ch} * metric_dg(x${ch}, g${ch}) * cw;
% for k, parts in sorted(jac[ch].items()):
        acc_g${k} += q * (${' + '.join(parts)});
% endfor
        }
% endfor
% endif
    }
% if ch_loop:
${reduce_and_write(['acc_l'], [('acc_g', n_free)])}
% else:
${reduce_and_write(['acc_l'] + ['acc_g%d' % k for k in range(n_free)])}
% endif
}

/* loss, J^T W r and the upper triangle of J^T W J (Gauss-Newton / Levenberg-Marquardt) */
__kernel __attribute__((reqd_work_group_size(1, ${wg}, 1))) void jtj(KARGS)
{
${prologue()}
% if ch_loop:
${arrays(n_free, len(pairs))}
% else:
    real_v acc_l = 0;
% for k in range(n_free):
    real_v acc_g${k} = 0;
% endfor
% for (a, b) in pairs:
    real_v acc_h${a}_${b} = 0;
% endfor
% endif
    for (int v = v0 + lid; v < v1; v += ${wg}) {
${cell_and_model()}
% if ch_loop:
        const real_v cw = ${'c.ci' if cosw else '(real_v)1'};
        for (int ch = 0; ch < ${n_ch}; ch++) {
${channel_model()}
${channel_residual()}
            acc_l += wc * r * r;
            const real_v dg = metric_dg(x, gx) * cw;
% for i, col, parts in loop_jac:
            const real_v u${i} = dg * (${' + '.join(parts)});
            acc_g[${col}] += wc * r * u${i};
% endfor
% for ia, ib, idx in loop_pairs:
            acc_h[${idx}] += wc * u${ia} * u${ib};
% endfor
        }
% else:
${residuals()}
% for ch in range(n_ch):
        {
        acc_l += w${ch} * r${ch} * r${ch};
        const real_v dg = metric_dg(x${ch}, g${ch}) * cw;
% for k, parts in sorted(jac[ch].items()):
        const real_v u${k} = dg * (${' + '.join(parts)});
        acc_g${k} += w${ch} * r${ch} * u${k};
% endfor
% for a in sorted(jac[ch]):
        {
        const real_v wu = w${ch} * u${a};
% for b in sorted(jac[ch]):
% if b >= a:
        acc_h${a}_${b} += wu * u${b};
% endif
% endfor
        }
% endfor
        }
% endfor
% endif
    }
% if ch_loop:
${reduce_and_write(['acc_l'], [('acc_g', n_free), ('acc_h', len(pairs))])}
% else:
${reduce_and_write(['acc_l'] + ['acc_g%d' % k for k in range(n_free)] + ['acc_h%d_%d' % ab for ab in pairs])}
% endif
}

% if meat:
/* the sandwich's middle term (brdfcl.optim.uncertainty): M = sum_cells w^2 g g^T, with g = sum_ch r dr
 * the cell's own gradient (all channels together: cells are the independent units), its upper
 * triangle row by row; a non-finite g counts as zero */
__kernel __attribute__((reqd_work_group_size(1, ${wg}, 1))) void meat(KARGS)
{
${prologue()}
    real_v acc_m[${n_meat}];
    for (int k = 0; k < ${n_meat}; k++) acc_m[k] = 0;
    for (int v = v0 + lid; v < v1; v += ${wg}) {
${cell_and_model()}
        real_v gc[${n_free}];
        for (int k = 0; k < ${n_free}; k++) gc[k] = 0;
% if ch_loop:
        const real_v cw = ${'c.ci' if cosw else '(real_v)1'};
        for (int ch = 0; ch < ${n_ch}; ch++) {
${channel_model()}
${channel_residual()}
            const real_v q = r * metric_dg(x, gx) * cw;
% for i, col, parts in loop_jac:
            gc[${col}] += q * (${' + '.join(parts)});
% endfor
        }
% else:
${residuals()}
% for ch in range(n_ch):
        {
        const real_v q = r${ch} * metric_dg(x${ch}, g${ch}) * cw;
% for k, parts in sorted(jac[ch].items()):
        gc[${k}] += q * (${' + '.join(parts)});
% endfor
        }
% endfor
% endif
        const real_v wsq = w * w;
        for (int k = 0; k < ${n_free}; k++) gc[k] = SEL(gc[k], (real_v)0, isfinite(gc[k]) == 0);
% for a in range(n_free):
        {
        const real_v wa = wsq * gc[${a}];
% for b in range(a, n_free):
        acc_m[${a * n_free - a * (a - 1) // 2 + b - a}] += wa * gc[${b}];
% endfor
        }
% endfor
    }
${reduce_and_write([], [('acc_m', n_meat)])}
}
% endif

/* every reported error at once: sum w r^2 for ${', '.join(n for n, _, _ in reported)}, sum w x_m^2, sum w */
__kernel __attribute__((reqd_work_group_size(1, ${wg}, 1))) void errors(KARGS)
{
${prologue()}
    real_v ${''.join('err_%s = 0, ' % n for n, _, _ in reported)}acc_mm = 0, acc_w = 0;
    for (int v = v0 + lid; v < v1; v += ${wg}) {
${cell_and_model()}
        const real_v cw = ${'c.ci' if cosw else '(real_v)1'};
% for ch in (['ch'] if ch_loop else range(n_ch)):
% if ch_loop:
        for (int ch = 0; ch < ${n_ch}; ch++) {
${channel_model()}
% else:
        {
        const real_v p = p${ch};
% endif
        const real_v m = VLOAD(M, ${ch} * n_cells + o);
        const real_v ww = SEL(w, (real_v)0, m != m);
        const real_v xm = SEL(m * cw, (real_v)0, m != m), xp = SEL(p * cw, (real_v)0, m != m);
% for n, gp, gm in reported:
        const real_v d_${n} = ${gp} - ${gm};
% endfor
% for n, _, _ in reported:
        err_${n} += ww * d_${n} * d_${n};
% endfor
        acc_mm += ww * xm * xm;
        acc_w += ww;
        }
% endfor
    }
${reduce_and_write(['err_' + n for n, _, _ in reported] + ['acc_mm', 'acc_w'])}
}

/* model values at every cell of the set for one parameter vector per evaluation: out (e, ${n_ch}, n);
 * evaluation e uses the geometry of material mat[e] (geo_stride 0: one geometry for all) */
__kernel void predict(__global const real *geom, const int n_cells, const int geo_stride,
                      __global const real *prm, __global const int *mat, __global real *out)
{
    const int e = get_global_id(0);
    const int v = get_global_id(1);
    if (v >= n_cells / ${vw}) return;
    __global const real *P = prm + (size_t)e * ${n_prm};
    __global const real *G = geom + (size_t)mat[e] * geo_stride;
% for s in slots:
% if not (ch_loop and s.channel is not None):
    const real ${s.cname} = P[${loop.index}];
% endif
% endfor
% for k in consts:
    const real ${k} = P[${n_slots + loop.index}];
% endfor
    {
${cell_and_model()}
% for ch in (['ch'] if ch_loop else range(n_ch)):
% if ch_loop:
        for (int ch = 0; ch < ${n_ch}; ch++) {
${channel_model()}
% else:
        {
        const real_v p = p${ch};
% endif
% if vw == 1:
        out[((size_t)e * ${n_ch} + ${ch}) * n_cells + o] = p;
% else:
        vstore${vw}(p, 0, out + ((size_t)e * ${n_ch} + ${ch}) * n_cells + o);
% endif
        }
% endfor
    }
}
