/* Shared types and the per-cell prologue.  The generator defines:
 *   real, real_v (vector of VW cells), cond_v (integer vector of the same width)
 * All term functions are written once for any vector width (1 on GPUs). */
#define PI_R ((real)M_PI)
#define INV_PI_R ((real)M_1_PI)
/* b where cond holds, lane by lane (OpenCL's select, written as the vector ?: so that it compiles
 * inline: the pip PoCL calls select() out of line, spilling every vector register) */
#define SEL(a, b, cond) ((cond) ? (b) : (a))

typedef struct {
    real_v sh, ch, cd, ci, co;   /* sin/cos theta_h, cos theta_d, cos theta_i, cos theta_o */
    real_v t2;                   /* tan^2 theta_h */
    real_v f0;                   /* 2 sin theta_h cos theta_d (times 1/lambda gives f) */
    real_v s5;                   /* (1 - cos theta_d)^5, Schlick */
    real_v t2i, t2o;             /* tan^2 theta_i, tan^2 theta_o */
    real_v gv;                   /* V-cavity G */
    real_v inv4cico;             /* 1 / (4 cos ti cos to) */
} cell_t;

/* Mirrors brdfcl/model/lobes/cells.py. */
inline cell_t make_cell(real_v sh, real_v ch, real_v cd, real_v ci, real_v co)
{
    cell_t c;
    c.sh = sh; c.ch = ch; c.cd = cd; c.ci = ci; c.co = co;
    real_v th = sh / ch;
    c.t2 = th * th;
    c.f0 = 2 * sh * cd;
    real_v m = 1 - cd, m2 = m * m;
    c.s5 = m2 * m2 * m;
    c.t2i = (1 - ci * ci) / (ci * ci);
    c.t2o = (1 - co * co) / (co * co);
    c.gv = fmin((real_v)1, 2 * ch * fmin(ci, co) / cd);
    c.inv4cico = (real)0.25 / (ci * co);
    return c;
}
