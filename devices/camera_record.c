/* Placeholder until the frame recorder lands. */
#include "camera_driver.h"

int kg_frame_recorder_open(const char *session_dir, const kg_camera_info *info,
                           const kg_frame_format *fmt, kg_frame_recorder **out, kg_err *err)
{
	return kg_fail(err, KG_ENOTSUP, "%s: recording is not implemented yet", session_dir);
}
int kg_frame_recorder_capture(kg_frame_recorder *r, const char *capture, kg_err *err)
{
	return KG_ENOTSUP;
}
int kg_frame_recorder_write(kg_frame_recorder *r, const kg_frame *f, kg_err *err)
{
	return KG_ENOTSUP;
}
void kg_frame_recorder_last(const kg_frame_recorder *r, char *file, size_t len,
                            char sha256[65])
{
}
int kg_frame_recorder_close(kg_frame_recorder **r, kg_err *err)
{
	return 0;
}
