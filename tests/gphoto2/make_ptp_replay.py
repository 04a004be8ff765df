#!/usr/bin/env python3
"""Synthesise a umockdev replay of a generic PTP camera (ISO 15740 over USB, Still
Image class 6/1/1) taking one picture, for libgphoto2's ptp2 driver (see README.md).

usage: make_ptp_replay.py DNG OUT_DIR [JPEG]

With JPEG, also the preview scenario: a camera with Nikon's live view serving JPEG
(behind a header) as its live-view images.

Writes OUT_DIR/ptpcam.umockdev (the device) and OUT_DIR/ptpcam.ioctl (the usbfs URBs
libgphoto2 submits and the camera's answers), serving DNG (a file the test wrote) as
the captured object. Deterministic; nothing here was recorded from hardware.
"""
import struct
import sys

DEVNODE = "/dev/bus/usb/001/002"
# config: pid.codes' test id, in no libgphoto2 table: the generic "USB PTP Class Camera"
GENERIC_ID = (0x1209, 0x0001)
# capture: the id of libgphoto2's "Nikon:Coolpix P5000 (PTP mode)", a model flagged as
# never sending ObjectAdded, so that ptp2 finds the new picture by listing the objects
# before and after InitiateCapture instead of waiting on the interrupt endpoint (which
# a umockdev replay cannot serve: README.md)
COOLPIX_ID = (0x04B0, 0x015B)
VENDOR_NIKON = 0x0000000A
EP_OUT, EP_IN, EP_INT = 0x01, 0x81, 0x82
MANUFACTURER, MODEL = "Kogei", "PTP Test Camera"
VERSION, SERIAL = "1.0", "KG0001"

# PTP codes (ISO 15740)
OC_GetDeviceInfo, OC_OpenSession, OC_CloseSession = 0x1001, 0x1002, 0x1003
OC_GetStorageIDs, OC_GetStorageInfo = 0x1004, 0x1005
OC_GetObjectHandles, OC_GetObjectInfo, OC_GetObject = 0x1007, 0x1008, 0x1009
OC_DeleteObject, OC_InitiateCapture = 0x100B, 0x100E
OC_GetDevicePropDesc, OC_GetDevicePropValue, OC_SetDevicePropValue = 0x1014, 0x1015, 0x1016
# Nikon's live view (libgphoto2's capture preview for Nikon cameras)
OC_NIKON_DeviceReady, OC_NIKON_StartLiveView, OC_NIKON_GetLiveViewImg = 0x90C8, 0x9201, 0x9203
DPC_NIKON_LiveViewStatus = 0xD1A2  # UINT8
LIVEVIEW_HEADER = 384  # bytes before the JPEG in a live-view image (skipped by ptp2)
PREVIEWS = 3
RC_OK = 0x2001
EC_ObjectAdded, EC_CaptureComplete = 0x4002, 0x400D
DPC_ExposureTime = 0x500D  # UINT32, 0.1 ms
DPC_ExposureIndex = 0x500F  # ISO
OFC_Association, OFC_TIFF = 0x3001, 0x380D  # the DNG is served as a TIFF object

CT_COMMAND, CT_DATA, CT_RESPONSE, CT_EVENT = 1, 2, 3, 4


def u16(v):
    return struct.pack("<H", v)


def u32(v):
    return struct.pack("<I", v)


def ptp_string(s):
    if not s:
        return b"\x00"
    chars = s + "\x00"
    return bytes([len(chars)]) + b"".join(u16(ord(c)) for c in chars)


STORAGE = 0x00010001


def u32_array(vals):
    return u32(len(vals)) + b"".join(u32(v) for v in vals)


def u16_array(vals):
    return u32(len(vals)) + b"".join(u16(v) for v in vals)


def container(ctype, code, tid, payload=b""):
    return u32(12 + len(payload)) + u16(ctype) + u16(code) + u32(tid) + payload


def descriptors(vid, pid):
    dev = bytes([18, 1, 0x00, 0x02, 0x00, 0x00, 0x00, 64,
                 vid & 0xFF, vid >> 8, pid & 0xFF, pid >> 8, 0x00, 0x01,
                 0, 0, 0, 1])  # no string descriptors (they would need control transfers)
    eps = [(EP_OUT, 2, 512, 0), (EP_IN, 2, 512, 0)]  # no interrupt endpoint: README
    intf = bytes([9, 4, 0, 0, len(eps), 6, 1, 1, 0])
    epd = b"".join(bytes([7, 5, a, t, m & 0xFF, m >> 8, i]) for a, t, m, i in eps)
    total = 9 + len(intf) + len(epd)
    cfg = bytes([9, 2, total & 0xFF, total >> 8, 1, 1, 0, 0xC0, 1])
    return dev + cfg + intf + epd


def device_file(vid, pid):
    d = descriptors(vid, pid).hex().upper()
    return "\n".join([
        "P: /devices/pci0000:00/0000:00:14.0/usb1/1-1",
        "N: bus/usb/001/002=" + d,
        "E: DEVNAME=" + DEVNODE,
        "E: DEVTYPE=usb_device",
        "E: DRIVER=usb",
        "E: PRODUCT=%x/%x/100" % (vid, pid),
        "E: SUBSYSTEM=usb",
        "E: BUSNUM=001",
        "E: DEVNUM=002",
        "E: MAJOR=189",
        "E: MINOR=1",
        "A: bConfigurationValue=1",
        "A: bDeviceClass=00",
        "A: bNumConfigurations=1",
        "A: bNumInterfaces= 1",
        "A: busnum=1",
        "A: devnum=2",
        "A: idProduct=%04x" % pid,
        "A: idVendor=%04x" % vid,
        "A: speed=480",
        "H: descriptors=" + d,
        "",
    ])


MAXPACKET = 512      # bulk endpoints' wMaxPacketSize (high speed)
READ_SIZE = 1024     # libgphoto2 reads a container into a 1024-byte buffer
READLEN = 512 * 1024  # and the rest of a long data phase in blobs of at most this


class Script:
    """usbfs URBs: bulk OUT at top level, the bulk IN answers indented under them."""

    def __init__(self):
        self.lines = ["@DEV " + DEVNODE, "USBDEVFS_GET_CAPABILITIES 0 7D000000"]
        self.tid = 0
        self.steps = []

    def out(self, data):
        self.lines.append("USBDEVFS_REAPURBNDELAY 0 3 %d 0 0 %d %d 0 %s"
                          % (EP_OUT, len(data), len(data), data.hex().upper()))

    def inn(self, data, buffer_len):
        self.lines.append(" USBDEVFS_REAPURBNDELAY 0 3 %d 0 0 %d %d 0 %s"
                          % (EP_IN, buffer_len, len(data), data.hex().upper()))

    def data_in(self, blob):
        """A data phase from the camera, cut as libgphoto2 reads it: the first 1024
        bytes, then blobs of whole packets, then the short rest."""
        self.inn(blob[:READ_SIZE], READ_SIZE)
        rest = blob[READ_SIZE:]
        while rest:
            n = len(rest)
            if n > READLEN:
                n = READLEN
            elif n > MAXPACKET:
                n -= n % MAXPACKET
            self.inn(rest[:n], n)
            rest = rest[n:]

    def transaction(self, what, code, params=(), data_out=None, data_in=None,
                    resp=RC_OK, resp_params=()):
        tid = self.tid
        self.tid += 1
        self.steps.append("%d %s" % (tid, what))
        self.out(container(CT_COMMAND, code, tid, b"".join(u32(p) for p in params)))
        if data_out is not None:
            blob = container(CT_DATA, code, tid, data_out)
            assert len(blob) < 1024 and len(blob) % MAXPACKET
            self.out(blob)
        if data_in is not None:
            self.data_in(container(CT_DATA, code, tid, data_in))
        self.inn(container(CT_RESPONSE, resp, tid, b"".join(u32(p) for p in resp_params)),
                 READ_SIZE)

    def text(self):
        return "\n".join(self.lines) + "\n"


ISO_CHOICES = [100, 200, 400, 800, 1600, 3200]
ISO_NOW, ISO_SET = 200, 800


def iso_desc(current):
    """DevicePropDesc of ExposureIndex: UINT16, get/set, an enumeration."""
    return (u16(DPC_ExposureIndex) + u16(0x0004) + bytes([1]) + u16(100) + u16(current)
            + bytes([2]) + u16(len(ISO_CHOICES)) + b"".join(u16(v) for v in ISO_CHOICES))


# ExposureTime in units of 0.1 ms: 1/125 s, 1/40 s, 0.3 s, 2 s, 30 s
EXPTIME_CHOICES = [80, 250, 3000, 20000, 300000]
EXPTIME_NOW = 250


def exptime_desc():
    """DevicePropDesc of ExposureTime: UINT32, get/set, an enumeration."""
    return (u16(DPC_ExposureTime) + u16(0x0006) + bytes([1]) + u32(80) + u32(EXPTIME_NOW)
            + bytes([2]) + u16(len(EXPTIME_CHOICES))
            + b"".join(u32(v) for v in EXPTIME_CHOICES))


CAPTURES = 2          # the one that learns the format at start, then one frame
HANDLE0 = 0x00010000


def object_info(handle, data, name):
    """ObjectInfo dataset of a picture in the root of the storage."""
    return (u32(STORAGE) + u16(OFC_TIFF) + u16(0) + u32(len(data)) + u16(0) + u32(0)
            + u32(0) + u32(0) + u32(64) + u32(48) + u32(16) + u32(0) + u16(0) + u32(0)
            + u32(0) + ptp_string(name) + ptp_string("20260101T120000")
            + ptp_string("20260101T120000") + ptp_string(""))


def device_info(vendor_ext, ops, events, props, capture_formats, image_formats):
    return (u16(100) + u32(vendor_ext) + u16(100) + ptp_string("") + u16(0)
            + u16_array(ops) + u16_array(events) + u16_array(props)
            + u16_array(capture_formats) + u16_array(image_formats)
            + ptp_string(MANUFACTURER) + ptp_string(MODEL) + ptp_string(VERSION)
            + ptp_string(SERIAL))


OPS = [OC_GetDeviceInfo, OC_OpenSession, OC_CloseSession, OC_GetStorageIDs,
       OC_GetStorageInfo, OC_GetObjectHandles, OC_GetObjectInfo, OC_GetObject,
       OC_DeleteObject, OC_InitiateCapture, OC_GetDevicePropDesc, OC_GetDevicePropValue,
       OC_SetDevicePropValue]


def open_and_describe(s, vendor, events, ops=OPS):
    """What libgphoto2 does on opening any camera: session, device info, storages, the
    objects on the card, the two property descriptions."""
    s.transaction("OpenSession", OC_OpenSession, [1])
    s.transaction("GetDeviceInfo", OC_GetDeviceInfo,
                  data_in=device_info(vendor, ops, events,
                                      [DPC_ExposureTime, DPC_ExposureIndex],
                                      [OFC_TIFF], [OFC_TIFF]))
    s.transaction("GetStorageIDs", OC_GetStorageIDs, data_in=u32_array([STORAGE]))
    s.transaction("GetObjectHandles (all storages, root: empty card)", OC_GetObjectHandles,
                  [0xFFFFFFFF, 0, 0xFFFFFFFF], data_in=u32_array([]))
    s.transaction("GetObjectHandles (storage, root: empty)", OC_GetObjectHandles,
                  [STORAGE, 0, 0xFFFFFFFF], data_in=u32_array([]))
    s.transaction("GetDevicePropDesc ExposureTime (shutter speed)", OC_GetDevicePropDesc,
                  [DPC_ExposureTime], data_in=exptime_desc())
    s.transaction("GetDevicePropDesc ExposureIndex (ISO)", OC_GetDevicePropDesc,
                  [DPC_ExposureIndex], data_in=iso_desc(ISO_NOW))


def config_scenario(s):
    """Open, read the two properties, set ISO and read it back, close."""
    open_and_describe(s, 0, [EC_ObjectAdded, EC_CaptureComplete])
    s.transaction("SetDevicePropValue ExposureIndex = %d" % ISO_SET, OC_SetDevicePropValue,
                  [DPC_ExposureIndex], data_out=u16(ISO_SET))
    s.transaction("GetDevicePropDesc ExposureIndex (read back)", OC_GetDevicePropDesc,
                  [DPC_ExposureIndex], data_in=iso_desc(ISO_SET))
    s.transaction("CloseSession", OC_CloseSession)


def capture_scenario(s, dng):
    """Open, capture one picture, download it, close."""
    open_and_describe(s, VENDOR_NIKON, [EC_ObjectAdded])
    for k in range(1, CAPTURES + 1):
        handles = [HANDLE0 + i for i in range(k - 1)]
        s.transaction("capture %d: GetObjectHandles before" % k, OC_GetObjectHandles,
                      [0xFFFFFFFF, 0, 0], data_in=u32_array(handles))
        s.transaction("capture %d: InitiateCapture" % k, OC_InitiateCapture, [0, 0])
        handle = HANDLE0 + k - 1
        s.transaction("capture %d: GetObjectHandles after (one new object)" % k,
                      OC_GetObjectHandles, [0xFFFFFFFF, 0, 0],
                      data_in=u32_array(handles + [handle]))
        s.transaction("capture %d: GetObjectInfo" % k, OC_GetObjectInfo, [handle],
                      data_in=object_info(handle, dng, "KG%05d.DNG" % k))
        s.transaction("capture %d: GetObject (the DNG, %d bytes)" % (k, len(dng)), OC_GetObject,
                      [handle], data_in=dng)
        s.transaction("capture %d: DeleteObject (?delete=1)" % k, OC_DeleteObject, [handle, 0])
        if k < CAPTURES:
            # a session that ends here (no raw decoder built in: the first capture
            # fails to decode); the next capture's transactions use the same ids
            s.transaction("CloseSession (if the session ends after capture %d)" % k,
                          OC_CloseSession)
            s.tid -= 1
    s.transaction("CloseSession", OC_CloseSession)


def preview_scenario(s, jpeg):
    """Open a camera with Nikon's live view, take PREVIEWS live-view images, close:
    no InitiateCapture anywhere (the replay answers nothing else)."""
    open_and_describe(s, VENDOR_NIKON, [EC_ObjectAdded],
                      OPS + [OC_NIKON_DeviceReady, OC_NIKON_StartLiveView,
                             OC_NIKON_GetLiveViewImg])
    s.transaction("GetDevicePropValue LiveViewStatus (off)", OC_GetDevicePropValue,
                  [DPC_NIKON_LiveViewStatus], data_in=bytes([0]))
    s.transaction("NIKON StartLiveView", OC_NIKON_StartLiveView)
    s.transaction("NIKON DeviceReady", OC_NIKON_DeviceReady)
    image = bytes(LIVEVIEW_HEADER) + jpeg
    s.transaction("NIKON GetLiveViewImg (the first image, skipped by ptp2)",
                  OC_NIKON_GetLiveViewImg, data_in=image)
    for k in range(1, PREVIEWS + 1):
        if k > 1:  # ptp2 reads the status on every preview; live view is on now
            s.transaction("preview %d: GetDevicePropValue LiveViewStatus (on)" % k,
                          OC_GetDevicePropValue, [DPC_NIKON_LiveViewStatus], data_in=bytes([1]))
        s.transaction("preview %d: NIKON GetLiveViewImg (%d-byte header, %d-byte JPEG)"
                      % (k, LIVEVIEW_HEADER, len(jpeg)), OC_NIKON_GetLiveViewImg,
                      data_in=image)
    s.transaction("CloseSession", OC_CloseSession)


def main():
    if len(sys.argv) not in (3, 4):
        sys.exit(__doc__)
    dng = open(sys.argv[1], "rb").read()
    out = sys.argv[2]
    jpeg = open(sys.argv[3], "rb").read() if len(sys.argv) == 4 else None
    scenarios = [("config", GENERIC_ID, config_scenario),
                 ("capture", COOLPIX_ID, lambda s: capture_scenario(s, dng))]
    if jpeg:
        scenarios.append(("preview", COOLPIX_ID, lambda s: preview_scenario(s, jpeg)))
    for name, ids, fill in scenarios:
        s = Script()
        fill(s)
        base = "%s/ptp-%s" % (out, name)
        with open(base + ".umockdev", "w") as f:
            f.write(device_file(*ids))
        with open(base + ".ioctl", "w") as f:
            f.write(s.text())
        with open(base + ".steps", "w") as f:
            f.write("".join("%s\n" % step for step in s.steps))
    # what the camera says, for the test's assertions
    with open(out + "/ptp.expect", "w") as f:
        f.write("manufacturer=%s\nmodel=%s\nserial=%s\n" % (MANUFACTURER, MODEL, SERIAL))
        f.write("iso_now=%d\niso_set=%d\niso_min=%d\niso_max=%d\n"
                % (ISO_NOW, ISO_SET, min(ISO_CHOICES), max(ISO_CHOICES)))
        f.write("exposure_now_us=%d\nexposure_min_us=%d\nexposure_max_us=%d\n"
                % (EXPTIME_NOW * 100, min(EXPTIME_CHOICES) * 100, max(EXPTIME_CHOICES) * 100))
        f.write("captures=%d\nfile1=KG00001.DNG\nfile2=KG00002.DNG\n" % CAPTURES)
        f.write("previews=%d\n" % PREVIEWS)


if __name__ == "__main__":
    main()
