/* sylva encode MODEL -o tree.sylva: a .sylva file from its JSON form (what
 * `sylva decode -o tree.json` writes, byte for byte the same file again) or
 * from any skeleton or QSM file (the skeleton alone, no cluster hulls). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline/commands.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/qsm/sylva_json.h"
#include "stages/qsm/qsm.h"


/* Reads MODEL: the JSON form when it is one, else any skeleton file. */
static sy_code read_model(const char *path, sy_skeleton *s, sy_clusters *cl, sy_sylva_meta *meta, int *has_quant,
                          sy_error *err)
{
    memset(cl, 0, sizeof *cl);
    *has_quant = 0;
    sy_buffer b;
    sy_code rc = sy_read_file(path, &b, err);
    if (rc) return rc;
    if (sy_skeleton_sniff(path, b.data, b.size) != SY_SKEL_JSON) {
        sy_buffer_free(&b);
        return sy_skeleton_read(path, s, err);
    }
    sy_jv *doc;
    rc = sy_jv_parse(path, (const char *)b.data, b.size, NULL, &doc, err);
    sy_buffer_free(&b);
    if (rc) return rc;
    rc = sy_sylva_json_is_tree(doc) ? sy_sylva_json_from_doc(path, doc, s, cl, meta, has_quant, err)
                                    : sy_skeleton_from_json(path, doc, -1, s, NULL, err);
    sy_jv_free(doc);
    return rc;
}

int cmd_encode(int argc, char **argv, sy_cli *cli)
{
    const char *out_path = NULL;
    int species = -1;
    const sy_opt opts[] = {
        {"-o", OPT_STRING, &out_path, "OUT.sylva", "the compact tree file to write"},
        {"--species", OPT_INT, &species, "ID", "species id to store (default: the JSON's, else 0: unknown)"},
        {NULL, 0, NULL, NULL, NULL},
    };
    const sy_cmd_spec spec = {
        "encode", "MODEL -o OUT.sylva", "Write a compact .sylva tree file from its JSON form or from a skeleton/QSM file.",
        "MODEL is a \"sylva-tree\" JSON (sylva decode -o tree.json: skeleton, cluster hulls, species,\n"
        "seed and quantisation grid; re-encoding it reproduces the original file byte for byte), or any\n"
        "skeleton file sylva reads (.json .ply .csv .obj, TreeQSM .txt; docs/qsm-formats.md), stored\n"
        "without clusters. The seed of a skeleton file is --seed. See docs/sylva-format.md.",
        opts, 1, 1};
    const char *in[1];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, in, 1, &n, SY_CLI_OUT_NONE, &rc)) return rc;
    char ext[16];
    sy_extension(out_path ? out_path : "", ext, sizeof ext);
    if (!out_path || strcmp(ext, "sylva") != 0 || species < -1 || species > 65535) {
        fprintf(stderr, "sylva encode: -o OUT.sylva is required; --species in 0..65535\n");
        return SY_EUSAGE;
    }
    if ((rc = sy_cli_check_outputs(&out_path, 1, in, 1))) return rc;
    sy_skeleton s;
    sy_clusters cl;
    sy_sylva_meta meta;
    memset(&meta, 0, sizeof meta);
    meta.seed = cli->seed;
    int has_quant;
    sy_error err = {0};
    if ((rc = read_model(in[0], &s, &cl, &meta, &has_quant, &err))) return sy_cli_report(&err);
    if (species >= 0) meta.species_id = (uint16_t)species;
    unsigned char *bytes = NULL;
    size_t size = 0;
    rc = sy_sylva_encode_meta(&s, &cl, &meta, has_quant, in[0], &bytes, &size, &err);
    if (!rc) rc = sy_write_file_atomic(out_path, bytes, size, &err);
    free(bytes);
    if (!rc) {
        if (cli->json) {
            sy_json j;
            sy_cli_json_open(&j, NULL, out_path);
            sy_json_int(&j, "bytes", (long long)size);
            sy_json_int(&j, "nodes", (long long)s.n);
            sy_json_int(&j, "clusters", (long long)cl.n);
            sy_json_int(&j, "species_id", meta.species_id);
            sy_cli_json_close(&j);
        } else if (!cli->quiet) {
            printf("%s: %zu nodes, %zu clusters, %zu bytes\n", out_path, s.n, cl.n, size);
        }
    }
    sy_skeleton_free(&s);
    sy_clusters_free(&cl);
    return rc ? sy_cli_report(&err) : 0;
}
