/* libcamera behind lc_shim.h. C++17; nothing here knows kogei's camera types, only
 * core's error convention. Exceptions never cross the C interface: allocation
 * failures become KG_ENOMEM. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#include <chrono>
#include <condition_variable>
#include <deque>
#include <memory>
#include <mutex>
#include <new>
#include <string>
#include <vector>

#include <libcamera/libcamera.h>

#include "lc_shim.h"

using namespace libcamera;

/* ---- the CameraManager ------------------------------------------------------------ */

namespace {

std::mutex manager_lock;
CameraManager *manager; /* under manager_lock */
int manager_refs;

/* Before libcamera's logger first runs (it reads the variable once). */
void quiet_logging()
{
	static std::once_flag once;
	std::call_once(once, [] { setenv("LIBCAMERA_LOG_LEVELS", "*:ERROR", 0); });
}

} /* namespace */

extern "C" int kg_lc_manager_ref(kg_err *err)
{
	quiet_logging();
	std::lock_guard<std::mutex> hold(manager_lock);
	if (manager_refs > 0) {
		manager_refs++;
		return 0;
	}
	try {
		manager = new CameraManager();
	} catch (const std::bad_alloc &) {
		return kg_fail(err, KG_ENOMEM, "libcamera: out of memory creating the CameraManager");
	}
	int ret = manager->start();
	if (ret) {
		delete manager;
		manager = nullptr;
		return kg_fail(err, KG_EIO, "libcamera %s: CameraManager::start failed: %s",
		               CameraManager::version().c_str(), strerror(-ret));
	}
	manager_refs = 1;
	return 0;
}

extern "C" void kg_lc_manager_unref(void)
{
	std::lock_guard<std::mutex> hold(manager_lock);
	if (manager_refs <= 0 || --manager_refs > 0)
		return;
	manager->stop();
	delete manager;
	manager = nullptr;
}

extern "C" int kg_lc_manager_refs(void)
{
	std::lock_guard<std::mutex> hold(manager_lock);
	return manager_refs;
}

extern "C" const char *kg_lc_version(void) { return CameraManager::version().c_str(); }

namespace {

/* The manager's cameras; the caller holds a reference. */
std::vector<std::shared_ptr<Camera>> list_cameras()
{
	std::lock_guard<std::mutex> hold(manager_lock);
	return manager ? manager->cameras() : std::vector<std::shared_ptr<Camera>>();
}

std::string model_of(const Camera &cam)
{
	std::optional<std::string> m = cam.properties().get(properties::Model);
	return m ? *m : std::string();
}

} /* namespace */

extern "C" int kg_lc_list(kg_lc_camera_fn fn, void *user, kg_err *err)
{
	int ret = kg_lc_manager_ref(err);
	if (ret)
		return ret;
	try {
		std::vector<std::shared_ptr<Camera>> cams = list_cameras();
		for (size_t i = 0; fn && i < cams.size(); i++)
			fn(user, (int)i, cams[i]->id().c_str(), model_of(*cams[i]).c_str());
		ret = (int)cams.size();
	} catch (const std::bad_alloc &) {
		ret = kg_fail(err, KG_ENOMEM, "libcamera: out of memory listing cameras");
	}
	kg_lc_manager_unref();
	return ret;
}

extern "C" void kg_lc_format_name(uint32_t fourcc, uint64_t modifier, char *buf, size_t len)
{
	quiet_logging();
	try {
		snprintf(buf, len, "%s", PixelFormat(fourcc, modifier).toString().c_str());
	} catch (const std::bad_alloc &) {
		snprintf(buf, len, "?");
	}
}

extern "C" int kg_lc_format_parse(const char *name, uint32_t *fourcc, uint64_t *modifier)
{
	quiet_logging();
	try {
		PixelFormat f = PixelFormat::fromString(name);
		if (!f.isValid())
			return KG_ENOENT;
		*fourcc = f.fourcc();
		*modifier = f.modifier();
		return 0;
	} catch (const std::bad_alloc &) {
		return KG_ENOMEM;
	}
}

/* ---- one camera --------------------------------------------------------------------- */

namespace {

const char *const control_names[KG_LC_NCONTROLS] = {
	"AeEnable",       "AwbEnable",      "ExposureTime",        "AnalogueGain",
	"ColourGains[0]", "ColourGains[1]", "FrameDurationLimits",
};

const ControlId *control_id(kg_lc_control k)
{
	switch (k) {
	case KG_LC_AE_ENABLE:
		return &controls::AeEnable;
	case KG_LC_AWB_ENABLE:
		return &controls::AwbEnable;
	case KG_LC_EXPOSURE_TIME:
		return &controls::ExposureTime;
	case KG_LC_ANALOGUE_GAIN:
		return &controls::AnalogueGain;
	case KG_LC_COLOUR_GAIN_RED:
	case KG_LC_COLOUR_GAIN_BLUE:
		return &controls::ColourGains;
	case KG_LC_FRAME_DURATION:
		return &controls::FrameDurationLimits;
	default:
		return nullptr;
	}
}

/* A scalar control value (or an array's element i) as a double. */
bool as_double(const ControlValue &v, size_t i, double *out)
{
	if (v.isNone() || (v.isArray() && i >= v.numElements()))
		return false;
	if (!v.isArray())
		i = 0;
	switch (v.type()) {
	case ControlTypeBool:
		*out = v.isArray() ? v.get<Span<const bool>>()[i] : v.get<bool>();
		return true;
	case ControlTypeByte:
		*out = v.isArray() ? v.get<Span<const uint8_t>>()[i] : v.get<uint8_t>();
		return true;
	case ControlTypeInteger32:
		*out = v.isArray() ? v.get<Span<const int32_t>>()[i] : v.get<int32_t>();
		return true;
	case ControlTypeInteger64:
		*out = (double)(v.isArray() ? v.get<Span<const int64_t>>()[i] : v.get<int64_t>());
		return true;
	case ControlTypeFloat:
		*out = v.isArray() ? v.get<Span<const float>>()[i] : v.get<float>();
		return true;
	default:
		return false;
	}
}

struct mapping {
	void *base = MAP_FAILED;
	size_t map_len = 0;
	const uint8_t *data = nullptr;
	size_t length = 0;
};

} /* namespace */

struct kg_lc_camera {
	std::shared_ptr<Camera> cam;
	bool acquired = false;
	std::unique_ptr<CameraConfiguration> tried, config;
	bool config_raw = false;
	std::unique_ptr<FrameBufferAllocator> alloc;
	Stream *stream = nullptr;
	std::vector<std::unique_ptr<Request>> requests; /* slot = index = cookie */
	std::vector<mapping> maps;
	std::vector<uint64_t> carried;                  /* settings generation per slot */
	bool streaming = false;

	/* filled on libcamera's thread */
	std::mutex lock;
	std::condition_variable cond;
	std::deque<Request *> done;
	bool unplugged = false;

	/* settings: what was asked, and what metadata said */
	double want[KG_LC_NCONTROLS] = {};
	bool want_set[KG_LC_NCONTROLS] = {};
	uint64_t generation = 1;
	double seen[KG_LC_NCONTROLS] = {};
	bool seen_valid[KG_LC_NCONTROLS] = {};
	bool seen_current[KG_LC_NCONTROLS] = {};

	void completed(Request *r)
	{
		std::lock_guard<std::mutex> hold(lock);
		done.push_back(r);
		cond.notify_one();
	}
	void disconnected()
	{
		std::lock_guard<std::mutex> hold(lock);
		unplugged = true;
		cond.notify_one();
	}
	void fill_controls(ControlList &list) const;
	void read_metadata(const ControlList &md, bool current);
	void unmap();
};

void kg_lc_camera::fill_controls(ControlList &list) const
{
	if (want_set[KG_LC_AE_ENABLE])
		list.set(controls::AeEnable, want[KG_LC_AE_ENABLE] != 0);
	if (want_set[KG_LC_AWB_ENABLE])
		list.set(controls::AwbEnable, want[KG_LC_AWB_ENABLE] != 0);
	if (want_set[KG_LC_EXPOSURE_TIME])
		list.set(controls::ExposureTime, (int32_t)lrint(want[KG_LC_EXPOSURE_TIME]));
	if (want_set[KG_LC_ANALOGUE_GAIN])
		list.set(controls::AnalogueGain, (float)want[KG_LC_ANALOGUE_GAIN]);
	if (want_set[KG_LC_COLOUR_GAIN_RED] || want_set[KG_LC_COLOUR_GAIN_BLUE]) {
		/* both gains travel together: the one not set keeps what the camera reported */
		float g[2];
		for (int i = 0; i < 2; i++) {
			int k = KG_LC_COLOUR_GAIN_RED + i;
			g[i] = (float)(want_set[k] ? want[k] : seen_valid[k] ? seen[k] : 1.0);
		}
		list.set(controls::ColourGains, {g[0], g[1]});
	}
	if (want_set[KG_LC_FRAME_DURATION]) {
		int64_t d = (int64_t)llrint(want[KG_LC_FRAME_DURATION]);
		list.set(controls::FrameDurationLimits, {d, d});
	}
}

void kg_lc_camera::read_metadata(const ControlList &md, bool current)
{
	double v[KG_LC_NCONTROLS];
	bool have[KG_LC_NCONTROLS] = {};
	if (auto x = md.get(controls::AeEnable))
		v[KG_LC_AE_ENABLE] = *x, have[KG_LC_AE_ENABLE] = true;
	if (auto x = md.get(controls::AwbEnable))
		v[KG_LC_AWB_ENABLE] = *x, have[KG_LC_AWB_ENABLE] = true;
	if (auto x = md.get(controls::ExposureTime))
		v[KG_LC_EXPOSURE_TIME] = *x, have[KG_LC_EXPOSURE_TIME] = true;
	if (auto x = md.get(controls::AnalogueGain))
		v[KG_LC_ANALOGUE_GAIN] = *x, have[KG_LC_ANALOGUE_GAIN] = true;
	if (auto x = md.get(controls::ColourGains)) {
		v[KG_LC_COLOUR_GAIN_RED] = (*x)[0], have[KG_LC_COLOUR_GAIN_RED] = true;
		v[KG_LC_COLOUR_GAIN_BLUE] = (*x)[1], have[KG_LC_COLOUR_GAIN_BLUE] = true;
	}
	if (auto x = md.get(controls::FrameDuration))
		v[KG_LC_FRAME_DURATION] = (double)*x, have[KG_LC_FRAME_DURATION] = true;
	for (int k = 0; k < KG_LC_NCONTROLS; k++) {
		if (!have[k])
			continue;
		seen[k] = v[k];
		seen_valid[k] = true;
		seen_current[k] = seen_current[k] || current;
	}
}

void kg_lc_camera::unmap()
{
	for (mapping &m : maps)
		if (m.base != MAP_FAILED)
			munmap(m.base, m.map_len);
	maps.clear();
}

extern "C" int kg_lc_open(const char *target, kg_lc_camera **out, kg_lc_identity *who,
                          kg_err *err)
{
	*out = nullptr;
	if (!target || !*target)
		return kg_fail(err, KG_EINVAL,
		               "expected libcamera:<id> or libcamera:<index> (see `kogei devices`)");
	int ret = kg_lc_manager_ref(err);
	if (ret)
		return ret;
	kg_lc_camera *c = nullptr;
	try {
		std::vector<std::shared_ptr<Camera>> cams = list_cameras();
		std::shared_ptr<Camera> cam;
		for (const auto &k : cams)
			if (k->id() == target)
				cam = k;
		char *end;
		long idx = strtol(target, &end, 10);
		if (!cam && *end == 0 && idx >= 0 && (size_t)idx < cams.size())
			cam = cams[(size_t)idx];
		if (!cam) {
			std::string ids;
			for (const auto &k : cams)
				ids += (ids.empty() ? ": " : ", ") + k->id();
			kg_lc_manager_unref();
			return kg_fail(err, KG_ENODEV,
			               "no libcamera camera with id or index '%s': libcamera %s sees %zu "
			               "camera%s%s",
			               target, CameraManager::version().c_str(), cams.size(),
			               cams.size() == 1 ? "" : "s", ids.c_str());
		}
		c = new kg_lc_camera();
		c->cam = cam;
		if ((ret = cam->acquire())) {
			ret = kg_fail(err, KG_EIO,
			              "libcamera camera '%s': Camera::acquire failed: %s%s",
			              cam->id().c_str(), strerror(-ret),
			              ret == -EBUSY ? " (another process or handle is using it)" : "");
			delete c;
			kg_lc_manager_unref();
			return ret;
		}
		c->acquired = true;
		cam->requestCompleted.connect(c, &kg_lc_camera::completed);
		cam->disconnected.connect(c, &kg_lc_camera::disconnected);
		memset(who, 0, sizeof(*who));
		snprintf(who->id, sizeof(who->id), "%s", cam->id().c_str());
		snprintf(who->model, sizeof(who->model), "%s", model_of(*cam).c_str());
		if (auto size = cam->properties().get(properties::PixelArraySize)) {
			who->sensor_width = (int)size->width;
			who->sensor_height = (int)size->height;
		}
	} catch (const std::bad_alloc &) {
		if (c) {
			if (c->acquired)
				c->cam->release();
			delete c;
		}
		kg_lc_manager_unref();
		return kg_fail(err, KG_ENOMEM, "libcamera: out of memory opening '%s'", target);
	}
	*out = c;
	return 0;
}

extern "C" void kg_lc_close(kg_lc_camera **pc)
{
	if (!pc || !*pc)
		return;
	kg_lc_camera *c = *pc;
	if (c->streaming)
		kg_lc_stop(c, nullptr);
	c->cam->requestCompleted.disconnect(c);
	c->cam->disconnected.disconnect(c);
	c->config.reset();
	c->tried.reset();
	if (c->acquired)
		c->cam->release();
	c->cam.reset();
	delete c;
	*pc = nullptr;
	kg_lc_manager_unref();
}

/* ---- controls ---------------------------------------------------------------------- */

extern "C" const char *kg_lc_control_name(kg_lc_control k)
{
	return (unsigned)k < KG_LC_NCONTROLS ? control_names[k] : "unknown";
}

extern "C" int kg_lc_control_range(kg_lc_camera *c, kg_lc_control k, double *min, double *max)
{
	const ControlId *id = control_id(k);
	*min = *max = 0;
	if (!id)
		return 0;
	const ControlInfoMap &info = c->cam->controls();
	auto it = info.find(id);
	if (it == info.end())
		return 0;
	if (id->type() == ControlTypeBool) {
		*max = 1;
		return 1;
	}
	double lo, hi;
	if (as_double(it->second.min(), 0, &lo) && as_double(it->second.max(), 0, &hi) && hi >= lo) {
		*min = lo;
		*max = hi;
	}
	return 1;
}

extern "C" int kg_lc_control_set(kg_lc_camera *c, kg_lc_control k, double v, kg_err *err)
{
	if ((unsigned)k >= KG_LC_NCONTROLS || !isfinite(v))
		return kg_fail(err, KG_EINVAL, "control %s: expected a finite value",
		               kg_lc_control_name(k));
	double lo, hi;
	if (!kg_lc_control_range(c, k, &lo, &hi))
		return kg_fail(err, KG_ENOTSUP, "the camera has no %s control", control_names[k]);
	c->want[k] = v;
	c->want_set[k] = true;
	c->generation++;
	for (bool &s : c->seen_current)
		s = false;
	return 0;
}

extern "C" int kg_lc_control_get(kg_lc_camera *c, kg_lc_control k, double *v, kg_err *err)
{
	if ((unsigned)k >= KG_LC_NCONTROLS)
		return kg_fail(err, KG_EINVAL, "control %d: unknown", (int)k);
	if (c->seen_current[k] || (!c->want_set[k] && c->seen_valid[k])) {
		*v = c->seen[k];
		return 0;
	}
	if (c->want_set[k]) {
		*v = c->want[k];
		return 0;
	}
	const ControlInfoMap &info = c->cam->controls();
	auto it = info.find(control_id(k));
	size_t i = k == KG_LC_COLOUR_GAIN_BLUE ? 1 : 0;
	if (it != info.end() && as_double(it->second.def(), i, v))
		return 0;
	return kg_fail(err, KG_ENOENT,
	               "%s: no value known (not set, no default, no frame captured yet)",
	               control_names[k]);
}

/* ---- configuration ------------------------------------------------------------------ */

extern "C" int kg_lc_try(kg_lc_camera *c, int raw, const uint32_t *fourccs, int n, int width,
                         int height, kg_lc_stream *got, char *note, size_t note_len,
                         kg_err *err)
{
	if (note && note_len)
		note[0] = 0;
	if (c->streaming)
		return kg_fail(err, KG_EINVAL, "configure: stop the stream first");
	try {
		std::unique_ptr<CameraConfiguration> cfg;
		if (raw)
			cfg = c->cam->generateConfiguration({StreamRole::Raw});
		else if (!(cfg = c->cam->generateConfiguration({StreamRole::StillCapture})))
			cfg = c->cam->generateConfiguration({StreamRole::Viewfinder});
		if (!cfg || cfg->empty())
			return kg_fail(err, KG_ENOTSUP, "the camera has no %s stream",
			               raw ? "raw (StreamRole::Raw)" : "processed (StillCapture)");
		StreamConfiguration &sc = cfg->at(0);
		std::vector<PixelFormat> offered = sc.formats().pixelformats();
		PixelFormat pick;
		for (int i = 0; i < n && !pick.isValid(); i++)
			for (const PixelFormat &f : offered)
				if (f == PixelFormat(fourccs[i]))
					pick = f;
		if (!pick.isValid() && n > 0)
			pick = PixelFormat(fourccs[0]);
		if (pick.isValid())
			sc.pixelFormat = pick;
		if (width > 0 && height > 0)
			sc.size = Size((unsigned)width, (unsigned)height);
		PixelFormat asked = sc.pixelFormat;
		Size asked_size = sc.size;
		CameraConfiguration::Status status = cfg->validate();
		if (status == CameraConfiguration::Invalid)
			return kg_fail(err, KG_EINVAL, "configure: libcamera finds %s %s invalid",
			               asked.toString().c_str(), asked_size.toString().c_str());
		if (note && status == CameraConfiguration::Adjusted)
			snprintf(note, note_len, "libcamera adjusted %s %s to %s %s", asked.toString().c_str(),
			         asked_size.toString().c_str(), sc.pixelFormat.toString().c_str(),
			         sc.size.toString().c_str());
		memset(got, 0, sizeof(*got));
		got->fourcc = sc.pixelFormat.fourcc();
		got->modifier = sc.pixelFormat.modifier();
		got->width = (int)sc.size.width;
		got->height = (int)sc.size.height;
		got->stride = sc.stride;
		got->frame_size = sc.frameSize;
		got->buffer_count = sc.bufferCount;
		got->raw = raw != 0;
		c->tried = std::move(cfg);
		c->config_raw = raw != 0;
		return 0;
	} catch (const std::bad_alloc &) {
		return kg_fail(err, KG_ENOMEM, "configure: out of memory");
	}
}

extern "C" int kg_lc_configure(kg_lc_camera *c, kg_err *err)
{
	if (!c->tried)
		return kg_fail(err, KG_EINVAL, "configure: no configuration validated yet");
	if (c->streaming)
		return kg_fail(err, KG_EINVAL, "configure: stop the stream first");
	int ret = c->cam->configure(c->tried.get());
	if (ret)
		return kg_fail(err, KG_EIO, "Camera::configure(%s) failed: %s",
		               c->tried->at(0).toString().c_str(), strerror(-ret));
	c->config = std::move(c->tried);
	return 0;
}

extern "C" void kg_lc_offered(kg_lc_camera *c, int raw, char *buf, size_t len)
{
	snprintf(buf, len, "none");
	try {
		std::unique_ptr<CameraConfiguration> cfg =
			c->cam->generateConfiguration({raw ? StreamRole::Raw : StreamRole::StillCapture});
		if (!cfg || cfg->empty())
			return;
		std::string s;
		for (const PixelFormat &f : cfg->at(0).formats().pixelformats())
			s += (s.empty() ? "" : ", ") + f.toString();
		if (!s.empty())
			snprintf(buf, len, "%s", s.c_str());
	} catch (const std::bad_alloc &) {
	}
}

/* ---- streaming ----------------------------------------------------------------------- */

namespace {

void release_stream(kg_lc_camera *c)
{
	{
		std::lock_guard<std::mutex> hold(c->lock);
		c->done.clear();
	}
	c->requests.clear();
	c->carried.clear();
	c->unmap();
	if (c->alloc && c->stream)
		c->alloc->free(c->stream);
	c->alloc.reset();
	c->stream = nullptr;
}

int queue(kg_lc_camera *c, size_t slot, kg_err *err)
{
	Request *r = c->requests[slot].get();
	c->fill_controls(r->controls());
	c->carried[slot] = c->generation;
	int ret = c->cam->queueRequest(r);
	if (ret)
		return kg_fail(err, KG_EIO, "Camera::queueRequest (buffer %zu) failed: %s", slot,
		               strerror(-ret));
	return 0;
}

} /* namespace */

extern "C" int kg_lc_start(kg_lc_camera *c, int nbuffers, kg_err *err)
{
	if (c->streaming)
		return 0;
	if (!c->config)
		return kg_fail(err, KG_EINVAL, "start: no pixel format configured");
	int ret;
	try {
		StreamConfiguration &sc = c->config->at(0);
		if (nbuffers > 0 && sc.bufferCount != (unsigned)nbuffers) {
			sc.bufferCount = (unsigned)nbuffers;
			if (c->config->validate() == CameraConfiguration::Invalid)
				return kg_fail(err, KG_EINVAL, "start: libcamera refuses %d buffers", nbuffers);
			if ((ret = c->cam->configure(c->config.get())))
				return kg_fail(err, KG_EIO, "start: Camera::configure (%u buffers) failed: %s",
				               sc.bufferCount, strerror(-ret));
		}
		c->stream = sc.stream();
		c->alloc = std::make_unique<FrameBufferAllocator>(c->cam);
		if ((ret = c->alloc->allocate(c->stream)) <= 0) {
			ret = kg_fail(err, KG_EIO, "FrameBufferAllocator::allocate (%s) failed: %s",
			              sc.toString().c_str(), ret ? strerror(-ret) : "no buffers");
			release_stream(c);
			return ret;
		}
		const std::vector<std::unique_ptr<FrameBuffer>> &bufs = c->alloc->buffers(c->stream);
		c->maps.resize(bufs.size());
		c->carried.assign(bufs.size(), 0);
		for (size_t i = 0; i < bufs.size(); i++) {
			const FrameBuffer::Plane &p = bufs[i]->planes()[0];
			mapping &m = c->maps[i];
			m.map_len = (size_t)p.offset + p.length;
			m.base = mmap(nullptr, m.map_len, PROT_READ, MAP_SHARED, p.fd.get(), 0);
			if (m.base == MAP_FAILED) {
				ret = kg_fail(err, KG_EIO, "mmap of buffer %zu (%zu bytes) failed: %s", i,
				              m.map_len, strerror(errno));
				release_stream(c);
				return ret;
			}
			m.data = (const uint8_t *)m.base + p.offset;
			m.length = p.length;
			std::unique_ptr<Request> r = c->cam->createRequest(i);
			if (!r || (ret = r->addBuffer(c->stream, bufs[i].get()))) {
				ret = kg_fail(err, KG_EIO, "Camera::createRequest / addBuffer (buffer %zu) failed",
				              i);
				release_stream(c);
				return ret;
			}
			c->requests.push_back(std::move(r));
		}
		ControlList start_controls(c->cam->controls());
		c->fill_controls(start_controls);
		{
			std::lock_guard<std::mutex> hold(c->lock);
			c->unplugged = false;
		}
		if ((ret = c->cam->start(&start_controls))) {
			ret = kg_fail(err, KG_EIO, "Camera::start failed: %s", strerror(-ret));
			release_stream(c);
			return ret;
		}
		c->streaming = true;
		for (size_t i = 0; i < c->requests.size(); i++)
			if ((ret = queue(c, i, err))) {
				kg_lc_stop(c, nullptr);
				return ret;
			}
		return 0;
	} catch (const std::bad_alloc &) {
		release_stream(c);
		return kg_fail(err, KG_ENOMEM, "start: out of memory");
	}
}

extern "C" int kg_lc_stop(kg_lc_camera *c, kg_err *err)
{
	if (!c->streaming)
		return 0;
	c->streaming = false;
	int ret = c->cam->stop(); /* cancelled requests complete before it returns */
	release_stream(c);
	if (ret)
		return kg_fail(err, KG_EIO, "Camera::stop failed: %s", strerror(-ret));
	return 0;
}

extern "C" int kg_lc_slots(const kg_lc_camera *c) { return (int)c->requests.size(); }

extern "C" int kg_lc_pop(kg_lc_camera *c, int timeout_ms, kg_lc_buffer *out, kg_err *err)
{
	if (!c->streaming)
		return kg_fail(err, KG_EINVAL, "pop: not streaming");
	Request *r = nullptr;
	{
		std::unique_lock<std::mutex> hold(c->lock);
		auto ready = [c] { return !c->done.empty() || c->unplugged; };
		if (timeout_ms < 0)
			c->cond.wait(hold, ready);
		else
			c->cond.wait_for(hold, std::chrono::milliseconds(timeout_ms), ready);
		if (c->done.empty()) {
			if (c->unplugged)
				return kg_fail(err, KG_ENODEV, "the camera was unplugged (disconnected)");
			return kg_fail(err, KG_ETIMEDOUT, "no request completed within %d ms", timeout_ms);
		}
		r = c->done.front();
		c->done.pop_front();
	}
	size_t slot = (size_t)r->cookie();
	FrameBuffer *fb = r->findBuffer(c->stream);
	if (slot >= c->requests.size() || !fb)
		return kg_fail(err, KG_EIO, "pop: completed request %zu has no buffer of the stream",
		               slot);
	const FrameMetadata &fm = fb->metadata();
	memset(out, 0, sizeof(*out));
	out->slot = (int)slot;
	out->data = c->maps[slot].data;
	out->length = c->maps[slot].length;
	out->bytesused = fm.planes().size() ? fm.planes()[0].bytesused : 0;
	out->sequence = fm.sequence;
	out->timestamp_ns = fm.timestamp;
	out->status = r->status() == Request::RequestCancelled || fm.status == FrameMetadata::FrameCancelled
	                  ? 2
	              : fm.status == FrameMetadata::FrameError ? 1
	                                                       : 0;
	const ControlList &md = r->metadata();
	auto exposure = md.get(controls::ExposureTime);
	auto gain = md.get(controls::AnalogueGain);
	out->exposure_us = exposure ? (double)*exposure : NAN;
	out->gain = gain ? (double)*gain : NAN;
	if (out->status == 0)
		c->read_metadata(md, c->carried[slot] == c->generation);
	return 0;
}

extern "C" int kg_lc_push(kg_lc_camera *c, int slot, kg_err *err)
{
	if (!c->streaming)
		return 0;
	if (slot < 0 || (size_t)slot >= c->requests.size())
		return kg_fail(err, KG_EINVAL, "push: buffer %d is not one of the stream's %zu", slot,
		               c->requests.size());
	c->requests[(size_t)slot]->reuse(Request::ReuseBuffers);
	return queue(c, (size_t)slot, err);
}
