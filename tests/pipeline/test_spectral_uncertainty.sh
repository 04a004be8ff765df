#!/bin/sh
# The spectral uncertainty of an estimate, on a session whose object is two flat greys
# (0.2 and 0.5) beside the CIE test colours: process.json's
# calibration.spectral_uncertainty holds, per band, the RMS of the method's leave-one-out
# errors over the chart (for the linear method recomputed here by refitting without
# each patch), labels.json carries the same record, the report draws it as a band and
# says what it is; the neutral tilt kogei records is the shape the cube's flat greys
# really got (truth: flat), and above 5 % process warns naming it, once.
# usage: test_spectral_uncertainty.sh KOGEI SOURCE_ROOT HAVE_TAGS_AND_DEMOSAIC
set -u
. "$(dirname "$0")/../lib.sh"
KOGEI=$1
ROOT=$2
. "$(dirname "$0")/sim_session.sh"
sim_session_needs "${3:-1}" numpy
case $KOGEI in /*) ;; *) KOGEI=$(pwd)/$KOGEI ;; esac
FIX=$ROOT/fixtures
kg_temp
cd "$T" || exit 1
fail=0
"$PY" -c "
print('patch,name,' + ','.join(str(400 + 5 * i) for i in range(61)))
print('1,grey20,' + ','.join(['0.2'] * 61))
print('2,grey50,' + ','.join(['0.5'] * 61))" >grey.csv
"$KOGEI" sim chart --layout cie-tcs-frame --spectra "$TCS" --camera "$FIX/demo/site_camera.csv" \
	--illuminant A --tilt 25 --width 800 --height 600 -o chart.tif >/dev/null &&
"$KOGEI" sim image --spectra grey.csv --materials default --only silver \
	--camera "$FIX/demo/site_camera.csv" --illuminant A --patch-size 80 --size 800x600 \
	-o object.tif --truth-labels truth.hdr >/dev/null &&
sim_acquire S dark chart.tif 10000 '&light=0' &&
sim_acquire S flat chart.tif 10000 '&uniform=0.6' &&
sim_acquire S chart chart.tif 10000 '' --layout cie-tcs-frame &&
sim_acquire S object object.tif 10000 '' --meta accession=G-1 &&
sim_measure chart.cgats || { echo "FAIL: the session could not be made"; exit 1; }
run_or_exit "$KOGEI" process S --spectra chart.cgats -o results
cp "$T/err" cli.txt

"$PY" - results chart.cgats truth.hdr cli.txt <<'PY' || fail=1
import json, re, sys
import numpy as np
res, cgats, truth, cli = sys.argv[1:5]
bad = []
def check(ok, what):
    if not ok:
        bad.append(what)
p = json.load(open(res + '/process.json'))
su = p['calibration']['spectral_uncertainty']
band = np.array(su['loo_band_rmse'], float)
check(band.shape == (61,) and np.all(np.isfinite(band)) and np.all(band > 0),
      'loo_band_rmse: 61 finite positive values, got %s' % band[:5])
lj = json.load(open(res + '/object-0001/labels.json'))
check(lj.get('spectral_uncertainty') == su, 'labels.json carries the calibration\'s record')

# the linear method's band, recomputed: refit without each patch (plain least squares)
ref = json.load(open(res + '/reference.json'))
text = open(cgats).read()
fmt = text.split('BEGIN_DATA_FORMAT')[1].split('END_DATA_FORMAT')[0].split()
rows = text.split('BEGIN_DATA\n')[1].split('END_DATA')[0].strip().split('\n')
spec = {r.split()[0]: np.array(r.split()[1:62], float) / 100 for r in rows}
ids = ref['training']['ids']
S = np.array([spec[i] for i in ids])
rho = np.array(ref['training']['rho'], float)
lin = ref['methods']['linear']
check(lin.get('ridge') in (None, 0, 0.0), 'linear has no ridge (the recomputation has none)')
# the neutral prior (the CIE test colours hold no neutral): flat greys read through the
# recorded white join every refit, counted `weight` times
npr = ref['neutral_prior']
check(npr['white_source'] == 'response' and npr['added'] and npr['tilt_before'] > 0.05,
      'the neutral prior added for a chart without neutrals: %s' % npr)
white = np.array(npr['white'], float)
levels = np.repeat([[0.05, 0.2, 0.5, 0.9]], npr['weight'], axis=0).ravel()
Vrgb = np.outer(levels, white)
Vs = np.outer(levels, np.ones(61))
err2 = np.zeros(61)
for i in range(len(S)):
    k = np.arange(len(S)) != i
    X, *_ = np.linalg.lstsq(np.vstack([rho[k], Vrgb]), np.vstack([S[k], Vs]), rcond=None)
    err2 += (rho[i] @ X - S[i]) ** 2
mine = np.sqrt(err2 / len(S))
got = np.array(lin['loo_band_rmse'], float)
check(np.allclose(got, mine, rtol=1e-6, atol=1e-9),
      'linear loo_band_rmse equals the refits\' (max diff %.3g)' % np.abs(got - mine).max())

# the cube's flat greys: their shape is the recorded neutral tilt (truth: flat)
h = open(res + '/object-0001/cube.hdr').read()
W = int(re.search(r'samples\s*=\s*(\d+)', h).group(1))
H = int(re.search(r'lines\s*=\s*(\d+)', h).group(1))
cube = np.fromfile(res + '/object-0001/cube.img', dtype='<f4').reshape(61, H, W)
th = open(truth).read()
lab = np.fromfile(truth.replace('.hdr', '.img'), dtype=np.uint8).reshape(H, W)
names = [n.strip() for n in re.search(r'class names\s*=\s*\{([^}]*)\}', th).group(1).split(',')]
ys, xs = np.nonzero(lab == names.index('chart'))
mid = (xs.min() + xs.max()) / 2
tilts = []
for sel, level in ((xs < mid, 0.2), (xs >= mid, 0.5)):
    cy, cx = int(np.median(ys[sel])), int(np.median(xs[sel]))
    s = cube[:, cy - 20:cy + 20, cx - 20:cx + 20].reshape(61, -1).mean(1)
    check(abs(s.mean() / level - 1) < 0.03, 'grey %.1f estimated at level %.3f' % (level, s.mean()))
    tilts.append(np.abs(s / s.mean() - 1).max())
tilt = su['neutral_tilt']
check(tilt is not None and all(abs(t - tilt) < 0.03 for t in tilts),
      'neutral_tilt %s is the cube greys\' shape %s (within 3 points)' % (tilt, tilts))
check(all(t <= 0.05 for t in tilts), 'the flat greys come out flat within 5 %%: %s' % tilts)
check(su['neutral_prior']['added'] and su['neutral_prior']['tilt_before'] == npr['tilt_before'],
      'process.json records the prior: %s' % su['neutral_prior'])
w = [m for m in p['warnings'] if 'flat grey' in m]
if tilt is not None and tilt > 0.05:
    check(len(w) == 1 and ('%.0f %%' % (100 * tilt)) in w[0],
          'one warning names the tilt: %s' % w)
    c = open(cli).read()
    check(c.count('estimates a flat grey') >= 1, 'the command line says it')
else:
    check(not w, 'no tilt warning below 5 %%: %s' % w)
print('\n'.join('FAIL: ' + b for b in bad))
sys.exit(1 if bad else 0)
PY

grep -q 'spectral uncertainty' results/report.html ||
	{ echo "FAIL: the report does not say what its band is"; fail=1; }

# calib reference on the same chart's readings: the prior brings the tilt within 5 %;
# without it (--no-neutral-prior) the fit keeps the tilt recorded as tilt_before
"$KOGEI" sim patches --spectra "$TCS" --camera "$FIX/demo/site_camera.csv" --illuminant A \
	-o tcs_rgb.cgats >/dev/null 2>&1 || { echo "FAIL: sim patches"; exit 1; }
run_or_exit "$KOGEI" calib reference --spectra "$TCS" --rgb tcs_rgb.cgats -o prior.json
run_or_exit "$KOGEI" calib reference --spectra "$TCS" --rgb tcs_rgb.cgats --no-neutral-prior \
	-o plain.json
"$PY" - prior.json plain.json <<'PY' || fail=1
import json, sys
prior, plain = (json.load(open(f))['neutral_prior'] for f in sys.argv[1:3])
bad = []
if not (prior['added'] and prior['tilt'] <= 0.05 < prior['tilt_before']):
    bad.append('the prior brings the tilt within 5 %%: %s' % prior)
if plain['added'] or abs(plain['tilt'] - prior['tilt_before']) > 1e-9:
    bad.append('--no-neutral-prior keeps the tilt of the fit without it: %s against %s'
               % (plain['tilt'], prior['tilt_before']))
print('\n'.join('FAIL: ' + b for b in bad))
sys.exit(1 if bad else 0)
PY
exit $fail
