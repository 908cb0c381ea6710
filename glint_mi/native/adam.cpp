// glint Adam on gathered rows: one pass over the touched rows of one field, with the arithmetic of the numpy
// reference (glint_mi.strategy.Adam.step) operation by operation, so the result is the same bit for bit:
//   the moments are float32 and their decays are float32 products (numpy multiplies a float32 array by a Python
//   float in float32), the gradient terms float64, each sum rounded to float32 as it is stored; the step is float64
//   from the stored float32 moments; the update is rounded to float32 before the float32 subtraction.
// The bias corrections c1 = 1 - b1^n, c2 = 1 - b2^n come from the caller (numpy's pow), one per row.
// Built into the same library as kbuffer.cpp, with -ffp-contract=off (a fused multiply-add would round differently).
#include <cmath>
#include <cstdint>

extern "C" {

// value, m, v: float32 [N, D]; g: float64 [N, D]; rows: the nr touched row indices; c1, c2: float64 [nr];
// lr: float64 [D] (the rate of each column).
void adam_rows(float *value, float *m, float *v, const double *g, const int64_t *rows, int64_t nr, int64_t D,
               const double *c1, const double *c2, const double *lr, double b1, double b2, double eps) {
    const float b1f = (float) b1, b2f = (float) b2;
    const double a1 = 1.0 - b1, a2 = 1.0 - b2;
    for (int64_t r = 0; r < nr; ++r) {
        const int64_t base = rows[r] * D;
        for (int64_t j = 0; j < D; ++j) {
            const int64_t e = base + j;
            const double gj = g[e];
            const float ms = (float) ((double) (b1f * m[e]) + a1 * gj);
            const float vs = (float) ((double) (b2f * v[e]) + a2 * gj * gj);
            m[e] = ms;
            v[e] = vs;
            const double step = ((double) ms / c1[r]) / (std::sqrt((double) vs / c2[r]) + eps);
            value[e] = value[e] - (float) (lr[j] * step);
        }
    }
}

}  // extern "C"
