/* sylva library list | show NAME: the species library's manifest (stable
 * ids, names, kinds, files), as text or --json. */
#include <stdio.h>
#include <string.h>

#include "pipeline/commands.h"
#include "species/library.h"
#include "stages/core/json.h"

static void print_entry_text(const sy_library *lib, const sy_library_entry *e)
{
    printf("id               %d\n", e->id);
    printf("name             %s\n", e->name);
    printf("scientific name  %s\n", e->scientific_name);
    printf("kind             %s\n", sy_species_kind_name(e->kind));
    printf("parameters       %s/%s\n", lib->dir, e->files[0]);
    for (size_t f = 1; f < e->n_files; f++) printf("file             %s/%s\n", lib->dir, e->files[f]);
    printf("leaf maps        none\n");
}

int cmd_library(int argc, char **argv, sy_cli *cli)
{
    const sy_opt opts[] = {{NULL, 0, NULL, NULL, NULL}};
    const sy_cmd_spec spec = {
        "library", "list | show NAME",
        "List the species library, or show one species: stable id, name, scientific name, kind, files.",
        "The library is the folder holding library.tsv: beside the executable, else in the installed\n"
        "data dir, else $SYLVA_LIBRARY (docs/species.md). Ids never change: scans' speciesID and\n"
        ".sylva species ids (id + 1) use them. --json prints a list of objects (show: one object)\n"
        "with id, name, scientific_name, kind, files and leaf_maps (null until a species has maps).",
        opts, 1, 2};
    const char *pos[2];
    int n, rc;
    if (!sy_cli_begin(&spec, argc, argv, cli, pos, 2, &n, SY_CLI_OUT_NONE, &rc)) return rc;
    int list = strcmp(pos[0], "list") == 0, show = strcmp(pos[0], "show") == 0;
    if ((!list && !show) || (list && n != 1) || (show && n != 2)) {
        fprintf(stderr, "sylva library: usage: sylva library list | sylva library show NAME\n");
        return SY_EUSAGE;
    }
    sy_error err = {0};
    sy_library lib;
    if (sy_library_load(NULL, &lib, &err)) return sy_cli_report(&err);
    const sy_library_entry *one = NULL;
    if (show && !(one = sy_library_find(&lib, pos[1]))) {
        sy_fail(&err, SY_EINPUT, "species \"%s\": not in the library %s/library.tsv", pos[1], lib.dir);
        sy_library_free(&lib);
        return sy_cli_report(&err);
    }
    if (cli->json) {
        sy_json j;
        sy_json_begin(&j, stdout, 0);
        if (one) sy_library_entry_json(one, &j);
        else {
            sy_json_array(&j, NULL);
            for (size_t i = 0; i < lib.n; i++) sy_library_entry_json(&lib.entries[i], &j);
            sy_json_end(&j);
        }
        sy_json_finish(&j);
    } else if (one) {
        print_entry_text(&lib, one);
    } else {
        printf("%-4s %-18s %-28s %-10s %s\n", "id", "name", "scientific name", "kind", "files");
        for (size_t i = 0; i < lib.n; i++) {
            const sy_library_entry *e = &lib.entries[i];
            printf("%-4d %-18s %-28s %-10s %s", e->id, e->name, e->scientific_name, sy_species_kind_name(e->kind),
                   e->files[0]);
            for (size_t f = 1; f < e->n_files; f++) printf(",%s", e->files[f]);
            printf("\n");
        }
        printf("(%zu species in %s)\n", lib.n, lib.dir);
    }
    sy_library_free(&lib);
    return 0;
}
