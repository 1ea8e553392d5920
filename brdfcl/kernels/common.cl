/* Shared macros; the per-cell type and prologue (cell_t, make_cell) are generated after them
 * (brdfcl.kernels.terms.cell_source).  The generator defines:
 *   real, real_v (vector of VW cells), cond_v (integer vector of the same width)
 * All term functions are written once for any vector width (1 on GPUs). */
#define PI_R ((real)M_PI)
#define INV_PI_R ((real)M_1_PI)
/* b where cond holds, lane by lane (OpenCL's select, written as the vector ?: so that it compiles
 * inline: the pip PoCL calls select() out of line, spilling every vector register) */
#define SEL(a, b, cond) ((cond) ? (b) : (a))
