/* The public header of core/: spectra on the 61-band grid, CGATS, colorimetry,
 * linear algebra, image and cube I/O, JSON helpers, plots, errors. Modules above
 * core include only this header. */
#ifndef KG_CORE_H
#define KG_CORE_H

#include "error.h"
#include "fsutil.h"
#include "memutil.h"
#include "text.h"
#include "spectrum.h"
#include "cgats.h"
#include "csv.h"
#include "colorimetry.h"
#include "linalg.h"
#include "envi.h"
#include "image.h"
#include "json.h"
#include "plot.h"
#include "rng.h"
#include "saturation.h"
#include "select.h"
#include "meta.h"
#include "mapfile.h"
#include "icc.h"
#include "escape.h"

#endif
