/* glint from C: a material, a few queries, samples with and without a footprint, an error.
 *
 * Checks the first query against the values tests/tests/stability.rs pins for it under the
 * default dense mode (the lattice's band with the tree: count 9.440415916772247,
 * f = 11.810939468564111, to 12 digits) and exits non-zero if anything fails. Built and run by
 * run.sh.
 *
 * Threads: a GlintMaterial is immutable once built, so one material may be shared by every
 * thread; each thread makes its own GlintScratch (glint_scratch_new) and passes it to its
 * queries. This example uses one thread. */
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "glint.h"

static const double PI = 3.14159265358979323846;

/* Exits with the library's message if a call failed. */
static void check(GlintStatus status, const char *what) {
    if (status != GLINT_OK) {
        fprintf(stderr, "%s failed (status %d): %s\n", what, (int)status, glint_last_error());
        exit(EXIT_FAILURE);
    }
}

/* Exits if a condition does not hold. */
static void expect(int condition, const char *what) {
    if (!condition) {
        fprintf(stderr, "check failed: %s\n", what);
        exit(EXIT_FAILURE);
    }
}

/* (sin θ cos φ, sin θ sin φ, cos θ): a direction in the shading frame, n = +z. */
static void direction(double theta, double phi, double out[3]) {
    out[0] = sin(theta) * cos(phi);
    out[1] = sin(theta) * sin(phi);
    out[2] = cos(theta);
}

int main(void) {
    printf("glint %s\n", glint_version());

    /* The paper's defaults: Beckmann alpha 0.1, N = 1e6 flakes per unit square, gamma 1 deg. */
    GlintMaterialParams params;
    check(glint_material_params_default(&params), "glint_material_params_default");
    GlintMaterial *material = NULL;
    check(glint_material_new(&params, &material), "glint_material_new");
    GlintScratch *scratch = NULL; /* this thread's */
    check(glint_scratch_new(&scratch), "glint_scratch_new");

    /* The lattice's band case of tests/tests/stability.rs: a 0.03 footprint (about 6 flakes
     * expected: the count blends the tree's particles and the lattice's draw). */
    GlintFootprint footprint = {{0.3, 0.6}, {0.03, 0.0}, {0.0, 0.03}};
    double wi[3], wo[3];
    direction(0.4, 0.3, wi);
    direction(0.36, 0.3 + PI, wo);
    GlintEvaluation e;
    check(glint_eval(material, scratch, &footprint, wi, wo, &e), "glint_eval");
    printf("pinned query: count %g, f_hat %.16g, nodes visited %" PRIu32 "\n", e.count,
           e.f_hat[0], e.nodes_visited);
    const double pinned_count = 9.440415916772247, pinned_f_hat = 11.810939468564111;
    expect(fabs(e.count - pinned_count) <= 1e-12 * pinned_count,
           "the count is the pinned 9.440415916772247");
    for (int c = 0; c < 3; c++) {
        expect(fabs(e.f_hat[c] - pinned_f_hat) <= 1e-12 * pinned_f_hat,
               "f_hat is the pinned 11.810939468564111");
    }

    /* More queries: the same directions over footprints of several sizes, with the expected
     * count and the smooth BRDF the glint BRDF converges to. */
    printf("%10s %8s %10s %12s %12s %6s\n", "footprint", "count", "expected", "f_hat",
           "f_smooth", "nodes");
    const double sizes[] = {0.001, 0.01, 0.03, 0.1};
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        GlintFootprint f = {{0.3, 0.6}, {sizes[i], 0.0}, {0.0, sizes[i]}};
        double expected, smooth[3];
        check(glint_eval(material, scratch, &f, wi, wo, &e), "glint_eval");
        check(glint_expected_count(material, scratch, &f, wi, wo, &expected),
              "glint_expected_count");
        check(glint_eval_smooth(material, wi, wo, smooth), "glint_eval_smooth");
        printf("%10g %8g %10.4g %12.6g %12.6g %6" PRIu32 "\n", sizes[i], e.count, expected,
               e.f_hat[0], smooth[0], e.nodes_visited);
    }

    /* Sampling: with the footprint, footprint_weight weighs with f_hat; smooth_weight weighs
     * with the smooth BRDF (for paths after the first bounce, which pass no footprint). The
     * direction and the pdf are the sampler's either way. */
    const double u[4] = {0.3, 0.6, 0.2, 0.9};
    const GlintFootprint *footprints[2] = {&footprint, NULL};
    for (int i = 0; i < 2; i++) {
        GlintSample s;
        check(glint_sample(material, scratch, footprints[i], wi, u, &s), "glint_sample");
        expect(s.valid, "these uniform numbers draw a sample");
        double pdf;
        check(glint_pdf(material, wi, s.wo, &pdf), "glint_pdf");
        printf("sample %s footprint: wo (%.6f, %.6f, %.6f), pdf %.6g, footprint_weight %.6g, "
               "smooth_weight %.6g\n",
               footprints[i] ? "with a" : "without", s.wo[0], s.wo[1], s.wo[2], s.pdf,
               s.footprint_weight[0], s.smooth_weight[0]);
        expect(pdf == s.pdf, "glint_pdf gives the sample's pdf");
    }

    /* Many rows at once (a renderer's wavefront): glint_eval_batch answers them in parallel on
     * glint's worker threads, no scratch needed, each row exactly as glint_eval answers it. */
    enum { ROWS = 64 };
    GlintFootprint rows[ROWS];
    double wis[3 * ROWS], wos[3 * ROWS];
    GlintEvaluation answers[ROWS];
    GlintStatus statuses[ROWS];
    for (int i = 0; i < ROWS; i++) {
        rows[i] = footprint;
        rows[i].uv[0] += 0.03 * i;
        direction(0.4, 0.3, wis + 3 * i);
        direction(0.36, 0.3 + PI, wos + 3 * i);
    }
    check(glint_eval_batch(material, ROWS, rows, wis, wos, answers, statuses),
          "glint_eval_batch");
    double found = 0.0;
    for (int i = 0; i < ROWS; i++) {
        GlintEvaluation one;
        check(glint_eval(material, scratch, &rows[i], wis + 3 * i, wos + 3 * i, &one),
              "glint_eval");
        expect(statuses[i] == GLINT_OK && one.count == answers[i].count &&
                   one.f_hat[0] == answers[i].f_hat[0],
               "a batch row is glint_eval's answer");
        found += answers[i].count;
    }
    printf("batch of %d footprints along u: %g particles found\n", ROWS, found);

    /* Maps: a density mask of 2 x 1 texels, flakes on the left half of the texture only.
     * Nearest (the default) keeps each texel constant; GLINT_MAP_FILTER_BILINEAR interpolates
     * between the texels' centres (u = 0.25 and 0.75 here), so the density at u = 0.375 is 1
     * and 0.75, and the smooth limit there scales with it. */
    const double mask[2] = {1.0, 0.0};
    GlintMaterialParams masked = params;
    masked.density_map = mask;
    masked.density_map_width = 2;
    masked.density_map_height = 1;
    const double at[2] = {0.375, 0.5};
    double smooth_at[2][3];
    const GlintMapFilter filters[2] = {GLINT_MAP_FILTER_NEAREST, GLINT_MAP_FILTER_BILINEAR};
    for (int i = 0; i < 2; i++) {
        masked.map_filter = filters[i];
        GlintMaterial *mapped = NULL;
        check(glint_material_new(&masked, &mapped), "glint_material_new (a density mask)");
        check(glint_eval_smooth_at(mapped, wi, wo, at, smooth_at[i]), "glint_eval_smooth_at");
        check(glint_material_free(mapped), "glint_material_free");
    }
    printf("density mask at u = 0.375: smooth f %.6g nearest, %.6g bilinear\n", smooth_at[0][0],
           smooth_at[1][0]);
    expect(smooth_at[0][0] > 0.0 &&
               fabs(smooth_at[1][0] - 0.75 * smooth_at[0][0]) <= 1e-12 * smooth_at[0][0],
           "the bilinear density at u = 0.375 is 0.75 of the nearest one");

    /* An error: gamma must be in (0, 60] degrees. */
    GlintMaterialParams wide = params;
    wide.gamma_degrees = 90.0;
    GlintMaterial *rejected = NULL;
    GlintStatus status = glint_material_new(&wide, &rejected);
    printf("gamma 90 degrees: status %d, \"%s\"\n", (int)status, glint_last_error());
    expect(status == GLINT_INVALID_PARAMETER && rejected == NULL,
           "an invalid gamma is GLINT_INVALID_PARAMETER");

    check(glint_scratch_free(scratch), "glint_scratch_free");
    check(glint_material_free(material), "glint_material_free");
    printf("ok\n");
    return EXIT_SUCCESS;
}
