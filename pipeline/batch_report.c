/* The batch products, from the trees' records: spatial voting for the
 * unconfident classifications (classify/vote.c: Pirk 2013's neighbourhood
 * vote), index.json, the foresters' trees.csv and report.html with its
 * three.js preview. Everything here is a function of the records, so a
 * Slurm array's last task, `sylva batch --collect` and a local run write
 * the same bytes. */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "pipeline/batch.h"
#include "pipeline/tree_species.h"
#include "species/library.h"
#include "stages/core/fileio.h"
#include "stages/core/json.h"
#include "stages/core/json_read.h"
#include "stages/eval/eval.h"

typedef struct {
    const char *id, *input;
    sy_jv *rec;          /* the record, NULL when the tree has none yet */
    const char *status;  /* ok, failed, pending */
    const char *error;
    const char *species; /* the decision after voting */
    const char *source;  /* manifest, option, classifier, voted, none */
    const char *label;
    double probability;
    int confident, voted, votes, has_position, thumbnail;
    double position[3];
    char species_buf[64];
} tree_row;

static const sy_jv *path_get(const sy_jv *v, const char *a, const char *b)
{
    v = v ? sy_jv_get(v, a) : NULL;
    return v && b ? sy_jv_get(v, b) : v;
}

static double num(const sy_jv *v, const char *a, const char *b)
{
    double x;
    const sy_jv *n = path_get(v, a, b);
    return n && sy_jv_number(n, &x) ? x : NAN;
}

static const char *str(const sy_jv *v, const char *a, const char *b) { return sy_jv_string(path_get(v, a, b)); }

static int flag(const sy_jv *v, const char *a, const char *b)
{
    const sy_jv *n = path_get(v, a, b);
    return n && n->type == SY_JV_BOOL && n->boolean;
}

/* Every record in out_dir/trees, sorted by id: the trees of a --collect
 * without inputs. */
static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

static sy_code list_records(const char *out_dir, char ***ids, size_t *n, sy_error *err)
{
    char dir[8192];
    snprintf(dir, sizeof dir, "%s/trees", out_dir);
    DIR *d = opendir(dir);
    *ids = NULL;
    *n = 0;
    if (!d) return sy_fail(err, SY_EINPUT, "%s: no batch here (%s)", out_dir, strerror(errno));
    size_t cap = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        size_t l = strlen(e->d_name);
        if (e->d_name[0] == '.' || l < 6 || strcmp(e->d_name + l - 5, ".json")) continue;
        if (*n == cap) {
            cap = cap ? 2 * cap : 64;
            char **p = realloc(*ids, cap * sizeof *p);
            if (!p) break;
            *ids = p;
        }
        char *s = malloc(l - 4);
        if (!s) break;
        memcpy(s, e->d_name, l - 5);
        s[l - 5] = 0;
        (*ids)[(*n)++] = s;
    }
    closedir(d);
    if (*n) qsort(*ids, *n, sizeof **ids, cmp_str);
    return SY_OK;
}

/* The plot records (out_dir/plots/ID.json of kind "plot") whose trees are in
 * the list, sorted by id. */
typedef struct {
    sy_jv **rec;
    size_t n;
} plot_list;

static void plots_load(const char *out_dir, const tree_row *t, size_t n_trees, plot_list *pl)
{
    memset(pl, 0, sizeof *pl);
    char dir[8192];
    snprintf(dir, sizeof dir, "%s/plots", out_dir);
    DIR *d = opendir(dir);
    if (!d) return;
    char **names = NULL;
    size_t n = 0, cap = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        size_t l = strlen(e->d_name);
        if (e->d_name[0] == '.' || l < 6 || strcmp(e->d_name + l - 5, ".json")) continue;
        if (n == cap) {
            cap = cap ? 2 * cap : 16;
            char **p = realloc(names, cap * sizeof *p);
            if (!p) break;
            names = p;
        }
        if (!(names[n] = malloc(l + 1))) break;
        memcpy(names[n++], e->d_name, l + 1);
    }
    closedir(d);
    if (n) qsort(names, n, sizeof *names, cmp_str);
    pl->rec = calloc(n ? n : 1, sizeof *pl->rec);
    for (size_t i = 0; i < n; i++) {
        char path[8500];
        snprintf(path, sizeof path, "%s/%s", dir, names[i]);
        sy_jv *r = NULL;
        sy_error e2 = {0};
        const char *kind = NULL, *id = NULL;
        if (pl->rec && !sy_jv_parse_file(path, &r, &e2)) kind = str(r, "kind", NULL), id = str(r, "id", NULL);
        int used = 0;
        if (kind && id && !strcmp(kind, "plot")) {
            size_t l = strlen(id);
            for (size_t k = 0; k < n_trees && !used; k++) used = !strncmp(t[k].id, id, l) && !strncmp(t[k].id + l, "_t", 2);
        }
        if (used) pl->rec[pl->n++] = r;
        else sy_jv_free(r);
        free(names[i]);
    }
    free(names);
}

static void plots_free(plot_list *pl)
{
    for (size_t i = 0; i < pl->n; i++) sy_jv_free(pl->rec[i]);
    free(pl->rec);
}

/* ------------------------------------------------------------ voting */

static sy_code vote(tree_row *t, size_t n, const sy_vote_options *vo, sy_error *err)
{
    size_t nc = 0;
    for (size_t i = 0; i < n; i++) {
        const sy_jv *p = path_get(t[i].rec, "classification", "probabilities");
        if (t[i].source && !strcmp(t[i].source, "classifier") && p && sy_jv_count(p) > nc) nc = sy_jv_count(p);
    }
    if (!nc) return SY_OK;
    /* Two sets: placed trees vote among themselves, the others are decided alone. */
    for (int placed = 0; placed < 2; placed++) {
        size_t m = 0;
        size_t *idx = calloc(n, sizeof *idx);
        double *prob = calloc(n * nc, sizeof *prob), *nov = calloc(n, sizeof *nov), *xy = calloc(2 * n, sizeof *xy);
        sy_tree_decision *dec = calloc(n, sizeof *dec);
        sy_code rc = SY_OK;
        if (!idx || !prob || !nov || !xy || !dec) rc = sy_fail(err, SY_EINTERNAL, "batch: out of memory");
        for (size_t i = 0; i < n && !rc; i++) {
            const sy_jv *p = path_get(t[i].rec, "classification", "probabilities");
            if (!t[i].source || strcmp(t[i].source, "classifier") || !p || t[i].has_position != placed) continue;
            for (size_t c = 0; c < sy_jv_count(p); c++) sy_jv_number(sy_jv_at(p, c), &prob[m * nc + c]);
            double v = num(t[i].rec, "classification", "novelty");
            nov[m] = isfinite(v) ? v : 0;
            xy[2 * m] = t[i].position[0];
            xy[2 * m + 1] = t[i].position[1];
            idx[m++] = i;
        }
        if (!rc && m) rc = sy_vote(m, nc, prob, nov, placed ? xy : NULL, vo, dec, err);
        for (size_t k = 0; k < m && !rc; k++) {
            tree_row *r = &t[idx[k]];
            r->confident = dec[k].confident;
            r->voted = dec[k].voted;
            r->votes = dec[k].votes;
            r->probability = prob[k * nc + (size_t)dec[k].best];
            const char *name = dec[k].species >= 0 ? sy_species_name_at(dec[k].species, r->species_buf, sizeof r->species_buf) : NULL;
            r->species = name ? name : "unknown";
            if (r->voted) r->source = "voted";
        }
        free(idx);
        free(prob);
        free(nov);
        free(xy);
        free(dec);
        if (rc) return rc;
    }
    return SY_OK;
}

/* ------------------------------------------------------- output helpers */

static void html_text(FILE *fp, const char *s)
{
    for (; s && *s; s++) {
        if (*s == '<') fputs("&lt;", fp);
        else if (*s == '>') fputs("&gt;", fp);
        else if (*s == '&') fputs("&amp;", fp);
        else if (*s == '"') fputs("&quot;", fp);
        else fputc(*s, fp);
    }
}

static void csv_field(FILE *fp, const char *s)
{
    if (!s) return;
    if (strpbrk(s, ",\"\n")) {
        fputc('"', fp);
        for (; *s; s++) {
            if (*s == '"') fputc('"', fp);
            fputc(*s, fp);
        }
        fputc('"', fp);
    } else fputs(s, fp);
}

static void csv_num(FILE *fp, double v, const char *fmt)
{
    fputc(',', fp);
    if (isfinite(v)) fprintf(fp, fmt, v);
}

static void fmt_num(char *buf, size_t size, double v, const char *fmt)
{
    if (isfinite(v)) snprintf(buf, size, fmt, v);
    else snprintf(buf, size, "–");
}

/* npm three: $SYLVA_THREE, beside the executable (a build tree's
 * ../node_modules/three), or the installed copy. */
static int find_three(char *out, size_t size)
{
    char cand[5][4200];
    int k = 0;
    const char *env = getenv("SYLVA_THREE");
    if (env && *env) snprintf(cand[k++], sizeof cand[0], "%s", env);
    char exe[4096];
    ssize_t len = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (len > 0) {
        exe[len] = 0;
        char *slash = strrchr(exe, '/');
        if (slash) {
            *slash = 0;
            snprintf(cand[k++], sizeof cand[0], "%s/../node_modules/three", exe);
            snprintf(cand[k++], sizeof cand[0], "%s/node_modules/three", exe);
            snprintf(cand[k++], sizeof cand[0], "%s/../share/sylva/three", exe);
        }
    }
#ifdef SYLVA_THREE_INSTALL_DIR
    snprintf(cand[k++], sizeof cand[0], "%s", SYLVA_THREE_INSTALL_DIR);
#endif
    for (int i = 0; i < k; i++) {
        char p[4300];
        if (snprintf(p, sizeof p, "%s/build/three.module.js", cand[i]) >= (int)sizeof p) continue;
        if (access(p, R_OK) == 0 && snprintf(out, size, "%s", cand[i]) < (int)size) return 1;
    }
    return 0;
}

/* The ES modules the preview needs, keyed as the page's loader resolves
 * their imports (three.js ships modules only, and a page opened from
 * file:// may not import files: the loader turns these texts into blob: URLs). */
static const char *const three_modules[][2] = {
    {"three.core.js", "build/three.core.js"},
    {"three.module.js", "build/three.module.js"},
    {"utils/BufferGeometryUtils.js", "examples/jsm/utils/BufferGeometryUtils.js"},
    {"utils/SkeletonUtils.js", "examples/jsm/utils/SkeletonUtils.js"},
    {"loaders/GLTFLoader.js", "examples/jsm/loaders/GLTFLoader.js"},
    {"controls/OrbitControls.js", "examples/jsm/controls/OrbitControls.js"},
    {"libs/meshopt_decoder.module.js", "examples/jsm/libs/meshopt_decoder.module.js"},
};

static sy_code write_three_bundle(const char *out_dir, char *why, size_t why_size, sy_error *err)
{
    char three[4200];
    if (!find_three(three, sizeof three)) {
        snprintf(why, why_size, "no 3D preview: npm three was not found (scripts/install-deps.sh installs it; or set SYLVA_THREE)");
        return SY_OK;
    }
    char dir[8192], path[8300];
    snprintf(dir, sizeof dir, "%s/report", out_dir);
    if (mkdir(dir, 0755) != 0 && errno != EEXIST)
        return sy_fail(err, SY_EINPUT, "%s: cannot create the folder: %s", dir, strerror(errno));
    snprintf(path, sizeof path, "%s/three-bundle.js", dir);
    sy_atomic_file f;
    sy_code rc = sy_atomic_open(&f, path, err);
    if (rc) return rc;
    fputs("/* three.js (MIT, see three-LICENSE) as module texts for report.html's loader. */\nwindow.sylvaModules = ", f.fp);
    sy_json j;
    sy_json_begin(&j, f.fp, 0);
    sy_json_object(&j, NULL);
    for (size_t i = 0; i < sizeof three_modules / sizeof *three_modules && !rc; i++) {
        char p[8300];
        snprintf(p, sizeof p, "%s/%s", three, three_modules[i][1]);
        sy_buffer b;
        if ((rc = sy_read_file(p, &b, err))) break;
        sy_json_string(&j, three_modules[i][0], (const char *)b.data);
        sy_buffer_free(&b);
    }
    sy_json_end(&j);
    fputs(";\n", f.fp);
    if (rc) {
        sy_atomic_abort(&f);
        return rc;
    }
    if ((rc = sy_atomic_commit(&f, err))) return rc;
    char lic[8300];
    snprintf(lic, sizeof lic, "%s/LICENSE", three);
    sy_buffer b;
    sy_error e2 = {0};
    if (!sy_read_file(lic, &b, &e2)) {
        snprintf(path, sizeof path, "%s/three-LICENSE", dir);
        rc = sy_write_file_atomic(path, b.data, b.size, err);
        sy_buffer_free(&b);
    }
    return rc;
}

/* ------------------------------------------------------------ the page */

static const char report_css[] =
    "body{font:14px/1.4 system-ui,sans-serif;margin:0;background:#f4f5f0;color:#1d261c}"
    "header{background:#24402a;color:#fff;padding:14px 24px}header h1{margin:0;font-size:22px}"
    "main{padding:12px 24px}section{margin:18px 0}h2{font-size:17px;margin:8px 0}"
    "table{border-collapse:collapse;background:#fff}td,th{border:1px solid #ccd3c6;padding:3px 8px;text-align:right}"
    "th{background:#e3e9dc}td.l,th.l{text-align:left}.grid{display:flex;flex-wrap:wrap;gap:10px}"
    ".card{background:#fff;border:1px solid #ccd3c6;width:200px;padding:6px;font-size:12px}"
    ".card img,.card .ph{width:200px;height:200px;display:block;object-fit:contain;background:#dfe6ee}"
    ".card .ph{display:flex;align-items:center;justify-content:center;text-align:center;color:#665;padding:8px;box-sizing:border-box}"
    ".card.failed{border-color:#b33}.card b{font-size:13px}.err{color:#a22}"
    "button{margin-top:4px}#viewer{position:fixed;right:16px;bottom:16px;width:520px;height:560px;background:#fff;"
    "border:2px solid #24402a;display:none;flex-direction:column}#viewer canvas{flex:1;width:100%;height:100%}"
    "#viewer .bar{display:flex;justify-content:space-between;padding:4px 8px;background:#24402a;color:#fff}"
    ".cm td{min-width:28px}.cm td.hit{background:#bfe3b4}.cm td.miss{background:#f3c7c0}";

/* The page's script: the module loader (blob: URLs from the bundle's
 * texts), then the preview: a tree's glb arrives as a script
 * (trees/ID.glb.js calls sylvaTree), GLTFLoader parses it, OrbitControls
 * turn it. window.__sylvaPreview reports what was drawn (the test reads it). */
static const char report_js[] =
    "(function(){\n"
    "const status=document.getElementById('preview-status');\n"
    "window.__sylvaReport={ready:false,errors:[]};\n"
    "addEventListener('error',e=>window.__sylvaReport.errors.push(String(e.message)));\n"
    "if(!window.sylvaModules){status.textContent=status.dataset.why||'no 3D preview: report/three-bundle.js is missing';"
    "window.__sylvaReport.ready=true;return;}\n"
    "const urls={};\n"
    "const resolve=s=>s==='three'?'three.module.js':s.replace(/^three\\/addons\\//,'').replace(/^(\\.\\.?\\/)+/,'');\n"
    "function url(name){if(urls[name]!==undefined)return urls[name];let src=window.sylvaModules[name];"
    "if(src===undefined)return null;urls[name]=null;" /* null while in progress: a comment naming the module itself */
    "src=src.replace(/(\\bfrom\\s*|\\bimport\\s*)(['\"])([^'\"\\n]+)\\2/g,(m,kw,q,spec)=>{const u=url(resolve(spec));return u?kw+q+u+q:m;});"
    "return urls[name]=URL.createObjectURL(new Blob([src],{type:'text/javascript'}));}\n"
    "try{Promise.all([import(url('three.module.js')),import(url('loaders/GLTFLoader.js')),import(url('controls/OrbitControls.js')),"
    "import(url('libs/meshopt_decoder.module.js'))]).then(([THREE,G,O,M])=>{\n"
    "const box=document.getElementById('viewer'),canvas=document.getElementById('view3d'),title=document.getElementById('view-title');\n"
    "let renderer=null,scene,camera,controls,pending={};\n"
    "function setup(){renderer=new THREE.WebGLRenderer({canvas,antialias:true,preserveDrawingBuffer:true});"
    "renderer.setPixelRatio(1);scene=new THREE.Scene();scene.background=new THREE.Color(0xdfe6ee);"
    "scene.add(new THREE.HemisphereLight(0xcfe3ff,0x4a3b2a,1.2));const sun=new THREE.DirectionalLight(0xfff4e0,2.2);"
    "sun.position.set(0.4,1,0.6);scene.add(sun);camera=new THREE.PerspectiveCamera(35,1,0.05,2000);"
    "controls=new O.OrbitControls(camera,canvas);controls.addEventListener('change',draw);}\n"
    "function draw(){const w=canvas.clientWidth,h=canvas.clientHeight;renderer.setSize(w,h,false);camera.aspect=w/h;"
    "camera.updateProjectionMatrix();renderer.render(scene,camera);}\n"
    "window.sylvaTree=(id,b64)=>{const bin=atob(b64),a=new Uint8Array(bin.length);for(let i=0;i<bin.length;i++)a[i]=bin.charCodeAt(i);"
    "const p=pending[id];delete pending[id];if(p)p(a.buffer);};\n"
    "function load(id){return new Promise((res,rej)=>{pending[id]=res;const s=document.createElement('script');"
    "s.src='trees/'+encodeURIComponent(id)+'.glb.js';s.onerror=()=>rej(new Error('trees/'+id+'.glb.js did not load'));"
    "document.head.appendChild(s);});}\n"
    "window.sylvaPreview=async id=>{const v={id,errors:[],triangles:0,done:false};window.__sylvaPreview=v;"
    "try{box.style.display='flex';title.textContent=id;if(!renderer)setup();"
    "for(const c of [...scene.children])if(c.userData.tree)scene.remove(c);"
    "const buf=await load(id);const loader=new G.GLTFLoader();loader.setMeshoptDecoder(M.MeshoptDecoder);"
    "const gltf=await loader.parseAsync(buf,'');const root=gltf.scene;root.userData.tree=1;scene.add(root);"
    "root.traverse(o=>{if(o.isMesh){const g=o.geometry;v.triangles+=(g.index?g.index.count:g.attributes.position.count)/3*(o.isInstancedMesh?o.count:1);}});"
    "const bb=new THREE.Box3().setFromObject(root),c=bb.getCenter(new THREE.Vector3()),s=bb.getSize(new THREE.Vector3());"
    "const r=Math.max(s.x,s.y,s.z);controls.target.copy(c);camera.position.set(c.x+r*1.3,c.y+r*0.35,c.z+r*1.3);"
    "camera.near=r/200;camera.far=r*20;camera.updateProjectionMatrix();controls.update();draw();"
    "const gl=renderer.getContext(),w=gl.drawingBufferWidth,h=gl.drawingBufferHeight,px=new Uint8Array(4*w*h);"
    "gl.readPixels(0,0,w,h,gl.RGBA,gl.UNSIGNED_BYTE,px);let k=0;for(let i=0;i<w*h;i++)"
    "if(Math.abs(px[4*i]-0xdf)+Math.abs(px[4*i+1]-0xe6)+Math.abs(px[4*i+2]-0xee)>30)k++;v.coverage=k/(w*h);"
    "}catch(e){v.errors.push(String(e&&e.message||e));}v.done=true;return v;};\n"
    "document.querySelectorAll('button[data-tree]').forEach(b=>b.addEventListener('click',()=>sylvaPreview(b.dataset.tree)));\n"
    "document.getElementById('view-close').addEventListener('click',()=>box.style.display='none');\n"
    "status.textContent='3D preview: press \"3D\" on a tree (drag to orbit, wheel to zoom).';\n"
    "window.__sylvaReport.ready=true;\n"
    "},e=>{status.textContent='no 3D preview: '+e;window.__sylvaReport.errors.push(String(e));window.__sylvaReport.ready=true;});\n"
    "}catch(e){status.textContent='no 3D preview: '+e;window.__sylvaReport.errors.push(String(e));window.__sylvaReport.ready=true;}\n"
    "})();\n";

static sy_code confusion_of(const tree_row *t, size_t n, sy_confusion *cm, int *have, sy_error *err)
{
    sy_label_table truth = {0}, pred = {0};
    sy_code rc = SY_OK;
    *have = 0;
    for (size_t i = 0; i < n && !rc; i++) {
        if (!t[i].label || strcmp(t[i].status, "ok")) continue;
        if (!(rc = sy_label_table_add(&truth, t[i].id, t[i].label, err)))
            rc = sy_label_table_add(&pred, t[i].id, t[i].species ? t[i].species : "unknown", err);
    }
    if (!rc && truth.n) {
        rc = sy_confusion_build(&truth, &pred, cm, err);
        *have = rc == SY_OK;
    }
    sy_label_table_free(&truth);
    sy_label_table_free(&pred);
    return rc;
}

static void write_html(FILE *fp, const tree_row *t, size_t n, const sy_confusion *cm, int have_cm, const char *three_why,
                       const plot_list *pl)
{
    size_t ok = 0, failed = 0, pending = 0;
    double total = 0, cpu = 0, stage[9] = {0};
    static const char *const stages[9] = {"ingest", "preprocess", "skeleton", "clusters", "classify", "synthesize", "mesh", "eval", "thumbnail"};
    for (size_t i = 0; i < n; i++) {
        if (!strcmp(t[i].status, "ok")) ok++;
        else if (!strcmp(t[i].status, "failed")) failed++;
        else pending++;
        double s = num(t[i].rec, "seconds", "total"), c = num(t[i].rec, "seconds", "cpu");
        if (isfinite(s)) total += s;
        if (isfinite(c)) cpu += c;
        for (int k = 0; k < 9; k++) {
            double v = num(t[i].rec, "seconds", stages[k]);
            if (isfinite(v)) stage[k] += v;
        }
    }
    fprintf(fp, "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>Sylva batch report</title>\n"
                "<style>%s</style></head><body>\n<header><h1>Sylva batch report</h1>"
                "<div>%zu trees: %zu made, %zu failed, %zu not yet run &middot; Sylva %s</div></header><main>\n",
            report_css, n, ok, failed, pending, SYLVA_VERSION);
    if (pl->n) {
        fprintf(fp, "<section id=\"plots\"><h2>Plots</h2><table><tr><th class=l>plot</th><th class=l>input</th><th>method</th>"
                    "<th>points</th><th>trees</th><th>ground</th><th>unassigned</th><th>seconds</th></tr>\n");
        for (size_t i = 0; i < pl->n; i++) {
            const sy_jv *r = pl->rec[i];
            fprintf(fp, "<tr><td class=l>");
            html_text(fp, str(r, "id", NULL));
            fprintf(fp, "</td><td class=l>");
            html_text(fp, str(r, "input", NULL));
            fprintf(fp, "</td><td>%s</td><td>%.0f</td><td>%zu</td><td>%.0f</td><td>%.0f</td><td>%.1f</td></tr>\n",
                    flag(r, "airborne", NULL) ? "canopy (airborne)" : "stems (terrestrial)", num(r, "points", NULL),
                    sy_jv_count(path_get(r, "trees", NULL)), num(r, "ground", NULL), num(r, "unassigned", NULL),
                    num(r, "seconds", NULL));
        }
        fprintf(fp, "</table></section>\n");
    }
    /* Species counts. */
    fprintf(fp, "<section id=\"species\"><h2>Species</h2><table><tr><th class=l>species</th><th>trees</th>"
                "<th>confident</th><th>by vote</th></tr>\n");
    const char *seen[512];
    size_t n_seen = 0;
    for (size_t i = 0; i < n; i++) {
        if (strcmp(t[i].status, "ok")) continue;
        const char *s = t[i].species ? t[i].species : "unknown";
        int dup = 0;
        for (size_t k = 0; k < n_seen && !dup; k++) dup = !strcmp(seen[k], s);
        if (dup || n_seen == 512) continue;
        seen[n_seen++] = s;
    }
    qsort(seen, n_seen, sizeof *seen, cmp_str);
    for (size_t k = 0; k < n_seen; k++) {
        size_t c = 0, conf = 0, voted = 0;
        for (size_t i = 0; i < n; i++)
            if (!strcmp(t[i].status, "ok") && !strcmp(t[i].species ? t[i].species : "unknown", seen[k]))
                c++, conf += (size_t)t[i].confident, voted += (size_t)t[i].voted;
        fprintf(fp, "<tr><td class=l>");
        html_text(fp, seen[k]);
        fprintf(fp, "</td><td>%zu</td><td>%zu</td><td>%zu</td></tr>\n", c, conf, voted);
    }
    fprintf(fp, "</table></section>\n");
    if (have_cm) {
        fprintf(fp, "<section id=\"confusion\"><h2>Confusion matrix (rows: label, columns: answer)</h2>"
                    "<p>accuracy %.3f, macro-F1 %.3f over %zu labelled trees</p><table class=cm><tr><th></th>",
                cm->accuracy, cm->macro_f1, cm->n_samples);
        for (size_t c = 0; c < cm->n_classes; c++) {
            fprintf(fp, "<th>");
            html_text(fp, cm->labels[c]);
            fprintf(fp, "</th>");
        }
        fprintf(fp, "</tr>\n");
        for (size_t r = 0; r < cm->n_classes; r++) {
            fprintf(fp, "<tr><th class=l>");
            html_text(fp, cm->labels[r]);
            fprintf(fp, "</th>");
            for (size_t c = 0; c < cm->n_classes; c++) {
                size_t v = cm->matrix[r * cm->n_classes + c];
                fprintf(fp, "<td%s>%zu</td>", v ? (r == c ? " class=hit" : " class=miss") : "", v);
            }
            fprintf(fp, "</tr>\n");
        }
        fprintf(fp, "</table></section>\n");
    }
    /* Failures. */
    fprintf(fp, "<section id=\"failures\"><h2>Failures (%zu)</h2>", failed);
    if (failed) {
        fprintf(fp, "<table><tr><th class=l>tree</th><th class=l>input</th><th class=l>error</th></tr>\n");
        for (size_t i = 0; i < n; i++) {
            if (strcmp(t[i].status, "failed")) continue;
            fprintf(fp, "<tr><td class=l>");
            html_text(fp, t[i].id);
            fprintf(fp, "</td><td class=l>");
            html_text(fp, t[i].input);
            fprintf(fp, "</td><td class=\"l err\">");
            html_text(fp, t[i].error ? t[i].error : "(no message)");
            fprintf(fp, "</td></tr>\n");
        }
        fprintf(fp, "</table>");
    } else fprintf(fp, "<p>none</p>");
    fprintf(fp, "</section>\n");
    /* Timings. */
    fprintf(fp, "<section id=\"timings\"><h2>Timings</h2><p>%.1f s of worker time over %zu trees (%.1f s per tree), "
                "%.1f s of CPU</p><table><tr>",
            total, ok + failed, ok + failed ? total / (double)(ok + failed) : 0, cpu);
    for (int k = 0; k < 9; k++) fprintf(fp, "<th>%s</th>", stages[k]);
    fprintf(fp, "</tr><tr>");
    for (int k = 0; k < 9; k++) fprintf(fp, "<td>%.1f s</td>", stage[k]);
    fprintf(fp, "</tr></table></section>\n");
    /* The trees. */
    fprintf(fp, "<section id=\"trees\"><h2>Trees</h2><p id=\"preview-status\" data-why=\"");
    html_text(fp, three_why);
    fprintf(fp, "\">3D preview loading&hellip;</p><div class=grid>\n");
    for (size_t i = 0; i < n; i++) {
        const tree_row *r = &t[i];
        int isok = !strcmp(r->status, "ok");
        fprintf(fp, "<div class=\"card%s\" id=\"tree-", isok ? "" : " failed");
        html_text(fp, r->id);
        fprintf(fp, "\">");
        if (isok && r->thumbnail) {
            fprintf(fp, "<img alt=\"thumbnail\" src=\"trees/");
            html_text(fp, r->id);
            fprintf(fp, ".png\">");
        } else {
            fprintf(fp, "<div class=ph>");
            html_text(fp, isok ? str(r->rec, "thumbnail_error", NULL) : !strcmp(r->status, "failed") ? "failed" : "not yet run");
            fprintf(fp, "</div>");
        }
        fprintf(fp, "<b>");
        html_text(fp, r->id);
        fprintf(fp, "</b><br>");
        if (isok) {
            char dbh[32], h[32], cw[32], vol[32], iou[32], p[32];
            fmt_num(dbh, sizeof dbh, num(r->rec, "metrics", "dbh") * 100, "%.1f cm");
            fmt_num(h, sizeof h, num(r->rec, "metrics", "height"), "%.1f m");
            fmt_num(cw, sizeof cw, num(r->rec, "metrics", "crown_width"), "%.1f m");
            fmt_num(vol, sizeof vol, num(r->rec, "metrics", "volume"), "%.3f m&sup3;");
            fmt_num(iou, sizeof iou, num(r->rec, "eval", "iou_mean"), "%.2f");
            fmt_num(p, sizeof p, r->probability, "%.2f");
            html_text(fp, r->species ? r->species : "unknown");
            fprintf(fp, " (%s%s)<br>DBH %s, height %s<br>crown %s, wood %s<br>silhouette IoU %s, %.1f s<br>"
                        "<button data-tree=\"",
                    r->voted ? "voted, p " : "p ", p, dbh, h, cw, vol, iou, num(r->rec, "seconds", "total"));
            html_text(fp, r->id);
            fprintf(fp, "\">3D</button>");
        } else {
            fprintf(fp, "<span class=err>");
            html_text(fp, r->error ? r->error : r->status);
            fprintf(fp, "</span>");
        }
        fprintf(fp, "</div>\n");
    }
    fprintf(fp, "</div></section>\n</main>\n<div id=\"viewer\"><div class=bar><span id=\"view-title\"></span>"
                "<a href=\"#\" id=\"view-close\" style=\"color:#fff\">close</a></div><canvas id=\"view3d\"></canvas></div>\n"
                "<script src=\"report/three-bundle.js\"></script>\n<script>\n%s</script>\n</body></html>\n",
            report_js);
}

/* ------------------------------------------------------------ products */

sy_code sy_batch_report(const sy_batch_inputs *in, const char *out_dir, const sy_batch_options *o, sy_error *err)
{
    char **ids = NULL;
    size_t n = 0;
    sy_code rc = SY_OK;
    if (in) n = in->n;
    else if ((rc = list_records(out_dir, &ids, &n, err))) return rc;
    tree_row *t = calloc(n ? n : 1, sizeof *t);
    if (!t) {
        for (size_t i = 0; i < n && ids; i++) free(ids[i]);
        free(ids);
        return sy_fail(err, SY_EINTERNAL, "batch: out of memory");
    }
    for (size_t i = 0; i < n; i++) {
        tree_row *r = &t[i];
        r->id = in ? in->items[i].id : ids[i];
        char path[8192];
        snprintf(path, sizeof path, "%s/trees/%s.json", out_dir, r->id);
        sy_error e2 = {0};
        if (access(path, F_OK) == 0 && sy_jv_parse_file(path, &r->rec, &e2)) r->rec = NULL;
        r->input = in ? in->items[i].path : str(r->rec, "input", NULL);
        r->status = str(r->rec, "status", NULL);
        if (!r->status) r->status = "pending";
        /* A record of another input or other options is not this tree's (yet). */
        if (in && r->rec) {
            char *opt = sy_batch_options_text(o, &in->items[i]);
            char ho[20];
            snprintf(ho, sizeof ho, "%016llx", opt ? (unsigned long long)sy_batch_hash(opt, strlen(opt)) : 0ull);
            free(opt);
            const char *rec_ho = str(r->rec, "options_hash", NULL);
            if (!rec_ho || strcmp(rec_ho, ho)) r->status = "pending";
        }
        r->error = str(r->rec, "error", NULL);
        r->label = str(r->rec, "label", NULL);
        if (!r->label && in) r->label = in->items[i].label;
        r->species = str(r->rec, "classification", "species");
        r->source = str(r->rec, "classification", "source");
        r->probability = num(r->rec, "classification", "probability");
        r->confident = flag(r->rec, "classification", "confident") || (r->source && strcmp(r->source, "classifier") &&
                                                                       strcmp(r->source, "none"));
        r->thumbnail = flag(r->rec, "thumbnail", NULL);
        const sy_jv *p = path_get(r->rec, "position", NULL);
        if (p && sy_jv_count(p) == 3) {
            r->has_position = 1;
            for (int k = 0; k < 3; k++) sy_jv_number(sy_jv_at(p, k), &r->position[k]);
        }
        if (strcmp(r->status, "ok")) r->species = NULL, r->source = NULL;
    }
    plot_list pl;
    plots_load(out_dir, t, n, &pl);
    sy_vote_options vo = o->vote;
    rc = vote(t, n, &vo, err);
    sy_confusion cm;
    memset(&cm, 0, sizeof cm);
    int have_cm = 0;
    if (!rc) rc = confusion_of(t, n, &cm, &have_cm, err);
    /* index.json */
    char path[8192];
    sy_atomic_file f;
    snprintf(path, sizeof path, "%s/index.json", out_dir);
    if (!rc && !(rc = sy_atomic_open(&f, path, err))) {
        sy_json j;
        sy_json_begin(&j, f.fp, 1);
        sy_json_object(&j, NULL);
        sy_json_string(&j, "sylva", SYLVA_VERSION);
        size_t ok = 0, failed = 0;
        for (size_t i = 0; i < n; i++) ok += !strcmp(t[i].status, "ok"), failed += !strcmp(t[i].status, "failed");
        sy_json_object(&j, "counts");
        sy_json_int(&j, "trees", (long long)n);
        sy_json_int(&j, "ok", (long long)ok);
        sy_json_int(&j, "failed", (long long)failed);
        sy_json_int(&j, "pending", (long long)(n - ok - failed));
        sy_json_end(&j);
        sy_json_array(&j, "trees");
        for (size_t i = 0; i < n; i++) {
            const tree_row *r = &t[i];
            sy_json_object(&j, NULL);
            sy_json_string(&j, "id", r->id);
            sy_json_string(&j, "input", r->input);
            sy_json_string(&j, "status", r->status);
            if (r->error) sy_json_string(&j, "error", r->error);
            if (r->label) sy_json_string(&j, "label", r->label);
            if (r->has_position) sy_json_numbers(&j, "position", r->position, 3);
            if (!strcmp(r->status, "ok")) {
                sy_json_string(&j, "species", r->species ? r->species : "unknown");
                sy_json_string(&j, "species_source", r->source ? r->source : "none");
                if (isfinite(r->probability)) sy_json_number(&j, "probability", r->probability);
                sy_json_bool(&j, "confident", r->confident);
                if (r->voted) sy_json_int(&j, "votes", r->votes);
                sy_json_object(&j, "metrics");
                static const char *const mk[] = {"dbh", "height", "crown_width", "volume"};
                for (int k = 0; k < 4; k++) sy_json_number(&j, mk[k], num(r->rec, "metrics", mk[k]));
                sy_json_end(&j);
                const sy_jv *ev = path_get(r->rec, "eval", NULL);
                if (ev) {
                    sy_json_object(&j, "eval");
                    for (size_t k = 0; k < sy_jv_count(ev); k++) sy_json_number(&j, ev->keys[k], ev->items[k].number);
                    sy_json_end(&j);
                }
                char f1[300];
                snprintf(f1, sizeof f1, "trees/%s.glb", r->id);
                sy_json_string(&j, "glb", f1);
                snprintf(f1, sizeof f1, "trees/%s.sylva", r->id);
                sy_json_string(&j, "sylva", f1);
                if (r->thumbnail) {
                    snprintf(f1, sizeof f1, "trees/%s.png", r->id);
                    sy_json_string(&j, "thumbnail", f1);
                } else sy_json_string(&j, "thumbnail_error", str(r->rec, "thumbnail_error", NULL));
            }
            double s = num(r->rec, "seconds", "total");
            if (isfinite(s)) sy_json_number(&j, "seconds", s);
            sy_json_end(&j);
        }
        sy_json_end(&j);
        sy_json_array(&j, "failures");
        for (size_t i = 0; i < n; i++) {
            if (strcmp(t[i].status, "failed")) continue;
            sy_json_object(&j, NULL);
            sy_json_string(&j, "id", t[i].id);
            sy_json_string(&j, "input", t[i].input);
            sy_json_string(&j, "error", t[i].error ? t[i].error : "");
            sy_json_end(&j);
        }
        sy_json_end(&j);
        if (pl.n) {
            sy_json_array(&j, "plots");
            for (size_t i = 0; i < pl.n; i++) {
                const sy_jv *r = pl.rec[i];
                sy_json_object(&j, NULL);
                sy_json_string(&j, "id", str(r, "id", NULL));
                sy_json_string(&j, "input", str(r, "input", NULL));
                sy_json_bool(&j, "airborne", flag(r, "airborne", NULL));
                sy_json_number(&j, "points", num(r, "points", NULL));
                sy_json_int(&j, "trees", (long long)sy_jv_count(path_get(r, "trees", NULL)));
                sy_json_number(&j, "ground", num(r, "ground", NULL));
                sy_json_number(&j, "unassigned", num(r, "unassigned", NULL));
                sy_json_end(&j);
            }
            sy_json_end(&j);
        }
        if (have_cm) {
            sy_json_object(&j, "confusion");
            sy_confusion_json(&cm, &j);
            sy_json_number(&j, "accuracy", cm.accuracy);
            sy_json_number(&j, "macro_f1", cm.macro_f1);
            sy_json_end(&j);
        }
        sy_json_end(&j);
        sy_json_finish(&j);
        rc = sy_atomic_commit(&f, err);
    }
    /* trees.csv, for foresters. */
    snprintf(path, sizeof path, "%s/trees.csv", out_dir);
    if (!rc && !(rc = sy_atomic_open(&f, path, err))) {
        fprintf(f.fp, "tree_id,x,y,z,species,probability,confident,voted,dbh_cm,height_m,crown_width_m,volume_m3,status,input\n");
        for (size_t i = 0; i < n; i++) {
            const tree_row *r = &t[i];
            csv_field(f.fp, r->id);
            for (int k = 0; k < 3; k++) csv_num(f.fp, r->has_position ? r->position[k] : NAN, "%.3f");
            fputc(',', f.fp);
            int isok = !strcmp(r->status, "ok");
            if (isok) csv_field(f.fp, r->species ? r->species : "unknown");
            csv_num(f.fp, isok ? r->probability : NAN, "%.3f");
            fprintf(f.fp, ",%s,%s", isok ? (r->confident ? "1" : "0") : "", isok ? (r->voted ? "1" : "0") : "");
            csv_num(f.fp, isok ? num(r->rec, "metrics", "dbh") * 100 : NAN, "%.1f");
            csv_num(f.fp, isok ? num(r->rec, "metrics", "height") : NAN, "%.2f");
            csv_num(f.fp, isok ? num(r->rec, "metrics", "crown_width") : NAN, "%.2f");
            csv_num(f.fp, isok ? num(r->rec, "metrics", "volume") : NAN, "%.4f");
            fputc(',', f.fp);
            csv_field(f.fp, r->status);
            fputc(',', f.fp);
            csv_field(f.fp, r->input);
            fputc('\n', f.fp);
        }
        rc = sy_atomic_commit(&f, err);
    }
    /* report.html and its three.js bundle. */
    char why[512] = "";
    if (!rc) rc = write_three_bundle(out_dir, why, sizeof why, err);
    snprintf(path, sizeof path, "%s/report.html", out_dir);
    if (!rc && !(rc = sy_atomic_open(&f, path, err))) {
        write_html(f.fp, t, n, &cm, have_cm, why, &pl);
        rc = sy_atomic_commit(&f, err);
    }
    if (have_cm) sy_confusion_free(&cm);
    plots_free(&pl);
    for (size_t i = 0; i < n; i++) sy_jv_free(t[i].rec);
    free(t);
    for (size_t i = 0; i < n && ids; i++) free(ids[i]);
    free(ids);
    return rc;
}
