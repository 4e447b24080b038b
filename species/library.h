/* The species library: the folder that holds the manifest (library.tsv) and
 * every species' files. The manifest fixes each species' id forever: the
 * LiDAR simulator's speciesID, the .sylva species id (library id + 1, 0 =
 * unknown) and the classifier's classes all use it, so adding a species never
 * renumbers anything. Manifest format: docs/species.md.
 *
 * Where the library is (sy_library_locate), first that holds library.tsv:
 *   1. beside the executable: <exe dir>/species, <exe dir>/../species (a build
 *      tree; CMake links build/species to the sources' species/), then
 *      <exe dir>/../share/sylva/species (a relocated install);
 *   2. the installed data dir, <CMAKE_INSTALL_FULL_DATADIR>/sylva/species;
 *   3. the folder named by the environment variable SYLVA_LIBRARY.
 * Nothing is cached: every call looks again, so callers on several threads
 * need no locks. */
#ifndef SYLVA_SPECIES_LIBRARY_H
#define SYLVA_SPECIES_LIBRARY_H

#include <stddef.h>

#include "species/params.h"
#include "stages/core/json.h"
#include "stages/core/status.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { SY_SPECIES_BROADLEAF = 0, SY_SPECIES_CONIFER = 1, SY_SPECIES_PALM = 2 } sy_species_kind;

/* "broadleaf", "conifer", "palm". */
const char *sy_species_kind_name(sy_species_kind kind);

typedef struct {
    int id;                /* stable, >= 0, unique in the manifest */
    char *name;            /* [a-z0-9_-]+, unique; the species' name everywhere */
    char *scientific_name; /* "Populus tremuloides" */
    sy_species_kind kind;
    size_t n_files;        /* >= 1 */
    char **files;          /* relative to the library folder; files[0] is the parameter .ini */
} sy_library_entry;

typedef struct {
    char dir[4096];            /* canonical absolute folder */
    size_t n;
    sy_library_entry *entries; /* in manifest order */
} sy_library;

/* Finds the library folder (see above) and writes its canonical path into
 * dir. SY_EINPUT naming the places looked at when none holds a manifest. */
sy_code sy_library_locate(char *dir, size_t size, sy_error *err);

/* Reads dir/library.tsv (dir NULL: sy_library_locate). Every malformed line,
 * duplicate id or name, unknown kind or file path leaving the folder fails
 * with "<manifest>:<line>: <problem>". Files are not opened here. */
sy_code sy_library_load(const char *dir, sy_library *lib, sy_error *err);
/* Parses manifest text; path names it in messages and dir fills lib->dir. */
sy_code sy_library_parse(const char *path, const char *dir, const char *text, size_t size, sy_library *lib,
                         sy_error *err);
void sy_library_free(sy_library *lib);

/* The entry named name or with id id; NULL when absent. */
const sy_library_entry *sy_library_find(const sy_library *lib, const char *name);
const sy_library_entry *sy_library_by_id(const sy_library *lib, int id);

/* The library id of name, -1 when it is not in the library or no library is
 * found (a tree of a species file outside the library is "unknown"). */
int sy_library_id(const char *name);

/* Loads the entry's Weber-Penn parameters (files[0]). */
sy_code sy_library_params(const sy_library *lib, const sy_library_entry *e, sy_species_params *sp, sy_error *err);

/* The entry as one JSON object (an array element when j is inside an
 * array): id, name, scientific_name, kind, files, and leaf_maps (null until
 * the species has leaf maps). */
void sy_library_entry_json(const sy_library_entry *e, sy_json *j);

#ifdef __cplusplus
}
#endif

#endif
