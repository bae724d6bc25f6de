/*
 * test_f1f2.c - the thesis's chapter 5.2 results on F1 and F2 sampled at
 * 0..3 with iso 0:
 *   F1: the centre cube has 6 positive corners, the centre-lower cube 2;
 *       MC leaves a hole on their shared face y = 1 (plus two more: F1 has
 *       three inverted combinations); Durst and DMC close them; DMC adds
 *       exactly the mending triangles it reports (6).
 *   F2: both cubes have 6 positive corners; MC and DMC are hole-free and
 *       keep the two lobes apart; DMC adds nothing; Durst adds a quad whose
 *       edges are used 3 times.
 */
#include "isomend.h"
#include "testutil.h"
#include "volumes.h"

#include <math.h>
#include <string.h>

typedef struct result {
    isomend_stats st;
    isomend_check_report r;
    isomend_mesh *mesh;
} result;

static void run(const float *v, isomend_method m, result *out)
{
    isomend_volume vol;
    isomend_volume_init(&vol, v, ISOMEND_F32, 4, 4, 4);
    isomend_options o;
    isomend_options_init(&o);
    o.method = m;
    CHECK_EQ_INT(isomend_extract(&vol, &o, &out->mesh, &out->st), ISOMEND_OK);
    CHECK_EQ_INT(isomend_mesh_check(out->mesh, &out->r), ISOMEND_OK);
}

static int positives(const float *v, int x, int y, int z)
{
    int n = 0;
    for (int c = 0; c < 8; c++)
        n += v[(x + (c & 1)) + 4 * (y + ((c >> 1) & 1)) + 16 * (z + ((c >> 2) & 1))] >= 0.0f;
    return n;
}

/* Once-used edges whose endpoints are both in the face y = 1, x and z in [1, 2]. */
static int hole_edges_on_centre_face(const isomend_mesh *m)
{
    const float *p = isomend_mesh_positions(m);
    const uint32_t *t = isomend_mesh_triangles(m);
    size_t nt = isomend_mesh_triangle_count(m);
    int found = 0;
    for (size_t i = 0; i < nt; i++)
        for (int e = 0; e < 3; e++) {
            uint32_t a = t[3 * i + e], b = t[3 * i + (e + 1) % 3];
            int uses = 0;
            for (size_t j = 0; j < nt; j++)
                for (int f = 0; f < 3; f++) {
                    uint32_t c = t[3 * j + f], d = t[3 * j + (f + 1) % 3];
                    uses += (c == a && d == b) || (c == b && d == a);
                }
            const float *pa = p + 3 * a, *pb = p + 3 * b;
            int on_face = pa[1] == 1.0f && pb[1] == 1.0f && pa[0] >= 1 && pa[0] <= 2 &&
                          pb[0] >= 1 && pb[0] <= 2 && pa[2] >= 1 && pa[2] <= 2 && pb[2] >= 1 &&
                          pb[2] <= 2;
            found += uses == 1 && on_face;
        }
    return found;
}

int main(void)
{
    float f1[64], f2[64];
    sample_4cubed(thesis_f1, f1);
    sample_4cubed(thesis_f2, f2);

    /* Figure-35: centre cube (1,1,1) and centre-lower cube (1,0,1). */
    CHECK_EQ_INT(positives(f1, 1, 1, 1), 6);
    CHECK_EQ_INT(positives(f1, 1, 0, 1), 2);
    CHECK_EQ_INT(positives(f2, 1, 1, 1), 6);
    CHECK_EQ_INT(positives(f2, 1, 0, 1), 6);

    result mc1, du1, dm1, mc2, du2, dm2;
    run(f1, ISOMEND_METHOD_MC, &mc1);
    run(f1, ISOMEND_METHOD_DURST, &du1);
    run(f1, ISOMEND_METHOD_DMC, &dm1);
    run(f2, ISOMEND_METHOD_MC, &mc2);
    run(f2, ISOMEND_METHOD_DURST, &du2);
    run(f2, ISOMEND_METHOD_DMC, &dm2);

    /* F1, MC: holes, one of them the quadrilateral on the centre/centre-lower face. */
    CHECK_EQ_INT(mc1.st.ambiguous_faces, 3);
    CHECK_EQ_INT(mc1.st.inverted_combinations, 3);
    CHECK_EQ_INT(mc1.r.hole_loops, 3);
    CHECK_EQ_INT(mc1.r.hole_edges, 12);
    CHECK_EQ_INT(hole_edges_on_centre_face(mc1.mesh), 4);
    /* F1, Durst and DMC: closed, and DMC's extra triangles are its mending ones. */
    CHECK_EQ_INT(du1.r.hole_edges, 0);
    CHECK_EQ_INT(du1.r.nonmanifold_edges, 0);
    CHECK_EQ_INT(dm1.r.hole_edges, 0);
    CHECK_EQ_INT(dm1.r.nonmanifold_edges, 0);
    CHECK_EQ_INT(dm1.r.misoriented_edges, 0);
    CHECK_EQ_INT(dm1.r.nonmanifold_vertices, 0);
    CHECK_EQ_INT(dm1.r.components, 1); /* F1 is a single continuous surface */
    CHECK_EQ_INT(dm1.st.triangles_by_origin[ISOMEND_ORIGIN_MEND], 6);
    CHECK_EQ_INT(dm1.st.triangles_by_origin[ISOMEND_ORIGIN_MEND],
                 2 * dm1.st.inverted_combinations);
    CHECK_EQ_INT(isomend_mesh_triangle_count(dm1.mesh),
                 isomend_mesh_triangle_count(mc1.mesh) + 6);
    {
        const uint8_t *o = isomend_mesh_triangle_origins(dm1.mesh);
        size_t mend = 0;
        for (size_t i = 0; i < isomend_mesh_triangle_count(dm1.mesh); i++)
            mend += o[i] == ISOMEND_ORIGIN_MEND;
        CHECK_EQ_INT(mend, 6);
    }
    CHECK_EQ_INT(hole_edges_on_centre_face(dm1.mesh), 0);

    /* F2: MC and DMC hole-free and identical, two lobes; Durst adds extraneous polygons. */
    CHECK_EQ_INT(mc2.st.ambiguous_faces, 1);
    CHECK_EQ_INT(mc2.st.inverted_combinations, 0);
    CHECK_EQ_INT(mc2.r.hole_edges, 0);
    CHECK_EQ_INT(mc2.r.nonmanifold_edges, 0);
    CHECK_EQ_INT(dm2.r.hole_edges, 0);
    CHECK_EQ_INT(dm2.r.nonmanifold_edges, 0);
    CHECK_EQ_INT(dm2.st.triangles_by_origin[ISOMEND_ORIGIN_MEND], 0);
    CHECK_EQ_INT(dm2.r.components, 2);
    CHECK_EQ_INT(isomend_mesh_triangle_count(dm2.mesh), isomend_mesh_triangle_count(mc2.mesh));
    CHECK(memcmp(isomend_mesh_triangles(dm2.mesh), isomend_mesh_triangles(mc2.mesh),
                 12 * isomend_mesh_triangle_count(mc2.mesh)) == 0);
    CHECK_EQ_INT(du2.st.triangles_by_origin[ISOMEND_ORIGIN_DURST], 2);
    CHECK_EQ_INT(du2.r.nonmanifold_edges, 2); /* the quad's edges on the MC segments */

    /* Normals are unit length and point to lower values (F grows with y). */
    {
        const float *n = isomend_mesh_normals(dm1.mesh);
        for (size_t i = 0; i < isomend_mesh_vertex_count(dm1.mesh); i++) {
            double len = sqrt(n[3 * i] * n[3 * i] + n[3 * i + 1] * n[3 * i + 1] +
                              n[3 * i + 2] * n[3 * i + 2]);
            CHECK(fabs(len - 1.0) < 1e-5);
            CHECK(n[3 * i + 1] < 0.0f); /* dF1/dy = 4 > 0: the normal points to -y */
        }
    }

    isomend_mesh_destroy(mc1.mesh);
    isomend_mesh_destroy(du1.mesh);
    isomend_mesh_destroy(dm1.mesh);
    isomend_mesh_destroy(mc2.mesh);
    isomend_mesh_destroy(du2.mesh);
    isomend_mesh_destroy(dm2.mesh);
    TEST_EXIT();
}
