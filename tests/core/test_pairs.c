/*
 * test_pairs.c - exhaustive pairs (the thesis's Table-1, chapter 4.2.2): all
 * 4096 sign patterns of two face-adjacent cubes, along each axis.
 *   - MC leaves a hole on the shared face exactly for inverted combinations
 *     (an ambiguous shared face, exactly one cube with 5+ positive corners):
 *     then 4 hole edges forming 1 loop, else none;
 *   - DMC never leaves an edge used once inside, 3+ times, or misoriented,
 *     and adds exactly 2 triangles per inverted combination;
 *   - Durst is hole-free and adds edges used 3 times exactly where MC had
 *     no hole on an ambiguous shared face.
 * Also: for one fixed ambiguous shared face, 110 of the 256 combinations of
 * the other 8 corners have holes under MC.
 */
#include "isomend.h"
#include "cpu_target.h"
#include "schedule.h"
#include "testutil.h"

#include "../../libcore/src/tables.h"

static int popcount(unsigned v)
{
    int n = 0;
    for (; v; v &= v - 1)
        n++;
    return n;
}

/* Configuration of cube `which` (0 or 1 along `axis`) in a 2-cube grid. */
static unsigned cube_config(const float *v, const int64_t dims[3], int axis, int which)
{
    unsigned cfg = 0;
    for (int c = 0; c < 8; c++) {
        int p[3] = {c & 1, (c >> 1) & 1, (c >> 2) & 1};
        p[axis] += which;
        cfg |= (unsigned)(v[p[0] + dims[0] * (p[1] + dims[1] * p[2])] >= 0.0f) << c;
    }
    return cfg;
}

int main(int argc, char **argv)
{
    if (cpu_target_from_args(argc, argv) || schedule_from_args(argc, argv))
        return 1;
    long holes_for_fixed_face = 0, fixed_face_cases = 0;
    for (int axis = 0; axis < 3; axis++) {
        int64_t dims[3] = {2, 2, 2};
        dims[axis] = 3;
        for (unsigned pattern = 0; pattern < 4096; pattern++) {
            float v[12];
            for (int s = 0; s < 12; s++)
                v[s] = ((pattern >> s) & 1) ? 1.0f : -1.0f;
            unsigned c0 = cube_config(v, dims, axis, 0), c1 = cube_config(v, dims, axis, 1);
            int ambiguous = (mc_ambiguous_faces[c0] >> (2 * axis + 1)) & 1;
            CHECK_EQ_INT(ambiguous, (mc_ambiguous_faces[c1] >> (2 * axis)) & 1);
            int inverted = ambiguous && ((popcount(c0) >= 5) != (popcount(c1) >= 5));

            isomend_volume vol;
            isomend_volume_init(&vol, v, ISOMEND_F32, dims[0], dims[1], dims[2]);
            isomend_options o;
            isomend_options_init(&o);
            o.threads = 1;
            isomend_check_report r[3];
            size_t nt[3];
            isomend_stats st[3];
            for (int m = 0; m < 3; m++) {
                isomend_mesh *mesh = NULL;
                o.method = (isomend_method)m;
                CHECK_EQ_INT(isomend_extract(&vol, &o, &mesh, &st[m]), ISOMEND_OK);
                CHECK_EQ_INT(isomend_mesh_check(mesh, &r[m]), ISOMEND_OK);
                nt[m] = isomend_mesh_triangle_count(mesh);
                isomend_mesh_destroy(mesh);
            }
            const isomend_check_report *mc = &r[ISOMEND_METHOD_MC],
                                       *du = &r[ISOMEND_METHOD_DURST],
                                       *dm = &r[ISOMEND_METHOD_DMC];
            CHECK_EQ_INT(st[0].ambiguous_faces, ambiguous);
            CHECK_EQ_INT(st[0].inverted_combinations, inverted);
            /* MC: a hole exactly for inverted combinations. */
            CHECK_EQ_INT(mc->hole_edges, inverted ? 4 : 0);
            CHECK_EQ_INT(mc->hole_loops, inverted ? 1 : 0);
            CHECK_EQ_INT(mc->nonmanifold_edges, 0);
            CHECK_EQ_INT(mc->misoriented_edges, 0);
            /* DMC: closed, manifold, oriented, 2 triangles per inverted combination. */
            CHECK_EQ_INT(dm->hole_edges, 0);
            CHECK_EQ_INT(dm->nonmanifold_edges, 0);
            CHECK_EQ_INT(dm->misoriented_edges, 0);
            CHECK_EQ_INT(dm->nonmanifold_vertices, 0);
            CHECK_EQ_INT(nt[ISOMEND_METHOD_DMC], nt[ISOMEND_METHOD_MC] + (inverted ? 2 : 0));
            /* Durst: no hole; edges used 3 times exactly where MC had no hole. */
            CHECK_EQ_INT(du->nonmanifold_edges > 0, ambiguous && !inverted);
            if (inverted) {
                CHECK_EQ_INT(du->hole_edges, 0);
                CHECK_EQ_INT(nt[ISOMEND_METHOD_DURST], nt[ISOMEND_METHOD_DMC]);
            }
            if (axis == 2) {
                /* shared face z = 1: corners (0,0) (1,0) (1,1) (0,1) = samples 4 5 7 6 */
                unsigned face = (pattern >> 4) & 0xF;
                if (face == 0x9) { /* samples 4 and 7 positive, 5 and 6 negative */
                    fixed_face_cases++;
                    holes_for_fixed_face += mc->hole_edges > 0;
                }
            }
        }
    }
    CHECK_EQ_INT(fixed_face_cases, 256);
    CHECK_EQ_INT(holes_for_fixed_face, 110);
    TEST_EXIT();
}
