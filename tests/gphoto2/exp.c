#include <stdio.h>
#include <stdlib.h>
#include <gphoto2/gphoto2.h>
#include "kg_camera.h"
static void logf_(GPLogLevel l, const char *d, const char *s, void *u){ fprintf(stderr,"[%s] %s\n", d, s);}
int main(int argc, char **argv){
  if (getenv("GPLOG")) gp_log_add_func(GP_LOG_DATA, logf_, NULL);
  kg_err e={{0}}; kg_camera *c=NULL;
  int r=kg_camera_open(argv[1], &c, &e);
  printf("open %d %s\n", r, e.msg);
  if (r) return 1;
  const kg_camera_info *i=kg_camera_get_info(c);
  printf("vendor '%s' model '%s' serial '%s' transport '%s'\n", i->vendor,i->model,i->serial,i->transport);
  for (int f=0; f<KG_FEAT_COUNT; f++){ kg_feature_info fi={0}; r=kg_camera_feature_info(c,f,&fi,&e); double v=0; int g= fi.available? kg_camera_get(c,f,&v,&e):0;
    printf("%s: r=%d avail %d w %d %g..%g native %s value %g (%d)\n", kg_feature_name(f), r, fi.available, fi.writable, fi.min, fi.max, fi.native, v, g);}
  if (argc>2 && *argv[2]){ double got; r=kg_camera_set(c, KG_FEAT_ISO, atof(argv[2]), &got, &e); printf("set %d %g %s\n", r, got, e.msg);}
  if (argc>3){ r=kg_camera_start(c,0,&e); printf("start %d %s\n", r, e.msg); kg_frame f; r=kg_camera_pop(c, 5000, &f, &e); printf("pop %d %s\n", r, e.msg);}
  kg_camera_free(&c); return 0; }
