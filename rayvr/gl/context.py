"""OpenGL contexts: headless EGL (default), headless OSMesa, and a glfw window.

Every context is OpenGL 4.3 core or newer (compute shaders, SSBOs, layered rendering).
`create_context()` tries the headless backends in order and, when none works, raises one
`ContextError` that lists each backend tried and why it failed.

moderngl covers almost everything; the few calls it lacks (glClipControl for reversed-Z,
layered depth attachments) go through `RawGL`, which resolves entry points with the
backend's own GetProcAddress.
"""
from __future__ import annotations

import ctypes
import ctypes.util
import logging
import os
from dataclasses import dataclass, field
from typing import Callable

import moderngl

REQUIRED_GL = 430
HEADLESS_BACKENDS = ("egl", "osmesa")

# Extensions rayvr looks for; `rayvr info` reports each one.
EXTENSIONS_OF_INTEREST = (
    "GL_ARB_clip_control",
    "GL_ARB_shader_viewport_layer_array",
    "GL_AMD_vertex_shader_layer",
    "GL_OVR_multiview",
    "GL_OVR_multiview2",
    "GL_NV_stereo_view_rendering",
    "GL_ARB_gpu_shader_int64",
    "GL_KHR_shader_subgroup",
    "GL_ARB_shader_ballot",
    "GL_NV_shader_atomic_float",
    "GL_ARB_bindless_texture",
)


class ContextError(RuntimeError):
    """No OpenGL context could be made (or it is too old)."""


class GpuError(ContextError):
    """The GL reported an error while a frame was drawn (out of memory, a failed dispatch)."""


# Raw GL entry points rayvr needs beyond moderngl: name -> (restype, argtypes).
_u, _i, _p = ctypes.c_uint, ctypes.c_int, ctypes.c_void_p
_RAW_SIGNATURES: dict[str, tuple] = {
    "glClipControl": (None, (_u, _u)),
    "glGenTextures": (None, (_i, ctypes.POINTER(_u))),
    "glDeleteTextures": (None, (_i, ctypes.POINTER(_u))),
    "glBindTexture": (None, (_u, _u)),
    "glActiveTexture": (None, (_u,)),
    "glTexStorage3D": (None, (_u, _i, _u, _i, _i, _i)),
    "glTexParameteri": (None, (_u, _u, _i)),
    "glGetTexImage": (None, (_u, _i, _u, _u, _p)),
    "glBindBuffer": (None, (_u, _u)),
    "glPixelStorei": (None, (_u, _i)),
    "glBindFramebuffer": (None, (_u, _u)),
    "glFramebufferTexture": (None, (_u, _u, _u, _i)),
    "glFramebufferTextureMultiviewOVR": (None, (_u, _u, _u, _i, _i, _i)),
    "glCheckFramebufferStatus": (_u, (_u,)),
    "glBindImageTexture": (None, (_u, _u, _i, ctypes.c_ubyte, _i, _u, _u)),
    "glClearBufferuiv": (None, (_u, _i, ctypes.POINTER(_u))),
    "glClearBufferfv": (None, (_u, _i, ctypes.POINTER(ctypes.c_float))),
    "glGetError": (_u, ()),
    "glGetIntegerv": (None, (_u, ctypes.POINTER(_i))),
    "glGetString": (ctypes.c_char_p, (_u,)),
    "glGetProgramiv": (None, (_u, _u, ctypes.POINTER(_i))),
    "glGetProgramBinary": (None, (_u, _i, ctypes.POINTER(_i), ctypes.POINTER(_u), _p)),
    # Timer queries with 64-bit results (moderngl reads 32 bits: passes over 4.29 s saturate).
    "glGenQueries": (None, (_i, ctypes.POINTER(_u))),
    "glDeleteQueries": (None, (_i, ctypes.POINTER(_u))),
    "glBeginQuery": (None, (_u, _u)),
    "glEndQuery": (None, (_u,)),
    "glGetQueryObjectui64v": (None, (_u, _u, ctypes.POINTER(ctypes.c_uint64))),
    # Fences: how many frames may be queued on the GPU (GLContext.fence).
    "glFenceSync": (_p, (_u, _u)),
    "glClientWaitSync": (_u, (_p, _u, ctypes.c_uint64)),
    "glDeleteSync": (None, (_p,)),
    # The driver's own words for an error (KHR_debug, core in 4.3): RAYVR_GL_DEBUG=1.
    "glEnable": (None, (_u,)),
    "glDebugMessageControl": (None, (_u, _u, _u, _i, ctypes.POINTER(_u), ctypes.c_ubyte)),
    "glGetDebugMessageLog": (_u, (_u, _i, ctypes.POINTER(_u), ctypes.POINTER(_u), ctypes.POINTER(_u),
                                  ctypes.POINTER(_u), ctypes.POINTER(_i), ctypes.c_char_p)),
}
GL_SYNC_GPU_COMMANDS_COMPLETE, GL_SYNC_FLUSH_COMMANDS_BIT = 0x9117, 0x1
GL_ALREADY_SIGNALED, GL_TIMEOUT_EXPIRED, GL_CONDITION_SATISFIED, GL_WAIT_FAILED = 0x911A, 0x911B, 0x911C, 0x911D
GL_GPU_MEMORY_INFO_DEDICATED_VIDMEM_NVX = 0x9047  # kB
GL_SHADING_LANGUAGE_VERSION = 0x8B8C
# The limits `rayvr info` reports, by their GL enums (moderngl's ctx.info lacks some of them).
INFO_LIMITS = {"GL_MAX_TEXTURE_SIZE": 0x0D33, "GL_MAX_ARRAY_TEXTURE_LAYERS": 0x88FF,
               "GL_MAX_SHADER_STORAGE_BLOCK_SIZE": 0x90DE, "GL_MAX_COMPUTE_WORK_GROUP_INVOCATIONS": 0x90EB,
               "GL_MAX_COMPUTE_SHARED_MEMORY_SIZE": 0x8262, "GL_MAX_COLOR_ATTACHMENTS": 0x8CDF,
               "GL_MAX_SAMPLES": 0x8D57}
GL_UNSIGNED_BYTE = 0x1401
GL_DEBUG_OUTPUT, GL_DEBUG_OUTPUT_SYNCHRONOUS, GL_DEBUG_TYPE_ERROR, GL_DONT_CARE = 0x92E0, 0x8242, 0x824C, 0x1100
DEBUG_ENV = "RAYVR_GL_DEBUG"  # 1: a frame's GL error names the call the driver refused (the suite sets it)
DEBUG_MESSAGES = 8  # driver messages a GpuError quotes
GL_ERROR_NAMES = {0x0500: "GL_INVALID_ENUM", 0x0501: "GL_INVALID_VALUE", 0x0502: "GL_INVALID_OPERATION",
                  0x0505: "GL_OUT_OF_MEMORY", 0x0506: "GL_INVALID_FRAMEBUFFER_OPERATION"}  # glGetError codes


class RawGL:
    """Entry points moderngl does not wrap, resolved once through GetProcAddress."""

    def __init__(self, get_proc_address: Callable[[str], int | None]):
        self._get = get_proc_address
        self._cache: dict[str, Callable] = {}

    def __getattr__(self, name: str) -> Callable:
        if name.startswith("_"):
            raise AttributeError(name)
        fn = self._cache.get(name)
        if fn is None:
            if name not in _RAW_SIGNATURES:
                raise AttributeError(f"RawGL has no signature for {name}")
            address = self._get(name)
            if not address:
                raise ContextError(f"the OpenGL driver does not provide {name}")
            restype, argtypes = _RAW_SIGNATURES[name]
            fn = ctypes.CFUNCTYPE(restype, *argtypes)(address)
            self._cache[name] = fn
        return fn

    def has(self, name: str) -> bool:
        try:
            getattr(self, name)
            return True
        except ContextError:
            return False


@dataclass
class Fence:
    """A GL sync object: `wait()` returns once the GPU has run every command before it; `ready()`
    says whether it has, without waiting."""

    raw: RawGL
    sync: int | None

    def wait(self) -> None:
        try:
            while True:  # short waits, flushing the first time: a driver may cap one wait's length
                status = self.raw.glClientWaitSync(self.sync, GL_SYNC_FLUSH_COMMANDS_BIT, 100_000_000)
                if status in (GL_ALREADY_SIGNALED, GL_CONDITION_SATISFIED):
                    return
                if status != GL_TIMEOUT_EXPIRED:
                    raise GpuError(f"waiting for the GPU failed (glClientWaitSync returned {status:#06x})")
        finally:
            self.release()

    def ready(self) -> bool:
        """Whether the GPU has passed the fence, without waiting (flushes, so that it will)."""
        status = self.raw.glClientWaitSync(self.sync, GL_SYNC_FLUSH_COMMANDS_BIT, 0)
        if status not in (GL_ALREADY_SIGNALED, GL_CONDITION_SATISFIED, GL_TIMEOUT_EXPIRED):
            raise GpuError(f"polling the GPU failed (glClientWaitSync returned {status:#06x})")
        return status != GL_TIMEOUT_EXPIRED

    def release(self) -> None:
        if self.sync:
            self.raw.glDeleteSync(self.sync)
            self.sync = None


@dataclass
class GLContext:
    """A moderngl context plus what rayvr needs to know about it."""

    ctx: moderngl.Context
    backend: str
    raw: RawGL
    _release: Callable[[], None] = field(default=lambda: None, repr=False)
    _parking: object = field(default=None, repr=False)
    _logging: bool = field(default=False, repr=False)  # log_errors is on
    said: list = field(default_factory=list, repr=False)  # the driver's messages of gl_errors' errors
    # Makes this context current again; a new context is current when made (every backend does that).
    _activate: Callable[[], None] = field(default=lambda: None, repr=False)

    def __post_init__(self):
        global _current
        _live.append(self)
        _current = self
        if os.environ.get(DEBUG_ENV, "") not in ("", "0"):
            self.log_errors()
        self._start_software_timers()

    def _start_software_timers(self) -> None:
        """Make a software rasterizer's first timer query read a time.

        llvmpipe records a query's start inside the scene it is binning, and a context has none
        before its first clear or draw: the first query of a context then has no start and reads
        the end timestamp alone (~ the machine's uptime), so the first pass of every run read
        "unavailable". Clearing a 1x1 framebuffer starts that scene; nothing else sees it."""
        if not is_software_renderer(self.ctx):
            return
        bound = self.ctx.fbo  # None on a new headless context: the parking framebuffer stays bound
        parking = self.parking_framebuffer()
        parking.use()
        parking.clear()
        if bound is not None:
            bound.use()

    def make_current(self) -> None:
        """Make this the thread's current context if another one is: GL calls go to the current
        context, and one made (or released) after this one would otherwise take them, every name
        of this one unknown there (glBindFramebuffer(non-gen name)). Renderer calls this on entry."""
        global _current
        if _current is not self:
            self._activate()
            _current = self

    def release_framebuffer(self, fbo) -> None:
        """Release `fbo`. If moderngl still counts it as the bound framebuffer, a live 1x1 one
        is bound first: moderngl rebinds its current framebuffer by name after some calls, and a
        deleted name there is GL_INVALID_OPERATION in the next Renderer on this context."""
        if getattr(self.ctx.fbo, "glo", None) == fbo.glo:
            self.parking_framebuffer().use()
        fbo.release()

    def parking_framebuffer(self):
        """A live 1x1 framebuffer of this context, made once, to bind when nothing else may be."""
        if self._parking is None:
            self._parking = self.ctx.framebuffer([self.ctx.renderbuffer((1, 1))])
        return self._parking

    def gl_errors(self) -> list[str]:
        """The GL errors raised since the last call (glGetError until GL_NO_ERROR), named; with
        log_errors on, `said` holds the driver's messages of the same span."""
        out: list[str] = []
        while len(out) < 16:  # a lost context may never return GL_NO_ERROR
            code = self.raw.glGetError()
            if code == 0:
                break
            out.append(GL_ERROR_NAMES.get(code, f"GL error {code:#06x}"))
        if self._logging:
            self.said = self.driver_messages()
        return out

    def log_errors(self) -> None:
        """Keep the driver's message for every GL error (KHR_debug's log, errors only), so that
        check_frame can say which call failed. Synchronous, so the log follows the calls' order;
        off by default (RAYVR_GL_DEBUG=1): a driver may slow down with debug output on."""
        raw = self.raw
        raw.glEnable(GL_DEBUG_OUTPUT)
        raw.glEnable(GL_DEBUG_OUTPUT_SYNCHRONOUS)
        raw.glDebugMessageControl(GL_DONT_CARE, GL_DONT_CARE, GL_DONT_CARE, 0, None, 0)
        raw.glDebugMessageControl(GL_DONT_CARE, GL_DEBUG_TYPE_ERROR, GL_DONT_CARE, 0, None, 1)
        self.driver_messages()  # what came before is not ours
        self._logging = True

    def driver_messages(self) -> list[str]:
        """The messages in the driver's debug log since the last call (empty unless log_errors)."""
        out: list[str] = []
        size = 4096
        text = ctypes.create_string_buffer(size)
        lengths = (ctypes.c_int * 1)()
        while len(out) < 64:
            if not self.raw.glGetDebugMessageLog(1, size, None, None, None, None, lengths, text):
                break
            out.append(text.value.decode(errors="replace").strip())
        return out

    def fence(self) -> "Fence":
        """A fence after every command recorded so far (Fence.wait blocks until the GPU passed it)."""
        return Fence(self.raw, self.raw.glFenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0))

    def check_frame(self, where: str) -> None:
        """Raise GpuError when the GL reported an error while `where` was drawn: a frame whose
        dispatches failed would otherwise come back as a plausible but wrong (often black) image."""
        errors = self.gl_errors()
        if errors:
            said = list(dict.fromkeys(self.said))[:DEBUG_MESSAGES]
            words = f": {'; '.join(said)}" if said else ""
            raise GpuError(f"{where}: the OpenGL driver reported {', '.join(dict.fromkeys(errors))} "
                           f"({self.ctx.info.get('GL_RENDERER', 'unknown renderer')}){words}; the image would be wrong")

    @property
    def extensions(self) -> set[str]:
        return self.ctx.extensions

    def has_extension(self, name: str) -> bool:
        return name in self.ctx.extensions

    def info(self) -> dict:
        """Vendor, renderer, version, limits and the extensions rayvr uses."""
        i = self.ctx.info
        limits = {k: i.get(k) if i.get(k) is not None else self._integer(enum) for k, enum in INFO_LIMITS.items()}
        return {
            "backend": self.backend,
            "vendor": i.get("GL_VENDOR"),
            "renderer": i.get("GL_RENDERER"),
            "version": i.get("GL_VERSION"),
            "glsl": i.get("GL_SHADING_LANGUAGE_VERSION") or self._string(GL_SHADING_LANGUAGE_VERSION),
            "version_code": self.ctx.version_code,
            "limits": limits,
            "extensions": {e: (e in self.ctx.extensions) for e in EXTENSIONS_OF_INTEREST},
        }

    def _integer(self, enum: int) -> int | None:
        """glGetIntegerv(enum), or None where the driver does not know it (a refused query leaves
        the value unwritten; the limits asked for are never negative)."""
        value = ctypes.c_int(-1)
        self.raw.glGetIntegerv(enum, ctypes.byref(value))
        return value.value if value.value >= 0 else None

    def _string(self, enum: int) -> str | None:
        value = self.raw.glGetString(enum)
        return value.decode("utf-8", "replace") if value else None

    @property
    def is_software(self) -> bool:
        return is_software_renderer(self.ctx)

    @property
    def max_ssbo_bytes(self) -> int:
        return int(self.ctx.info.get("GL_MAX_SHADER_STORAGE_BLOCK_SIZE") or 0)

    @property
    def max_texture_size(self) -> int:
        return int(self.ctx.info.get("GL_MAX_TEXTURE_SIZE") or 0)

    @property
    def memory_bytes(self) -> int | None:
        """Memory a frame's resources may take: the GPU's own where the driver says
        (GL_NVX_gpu_memory_info), the machine's RAM for a software rasterizer, else None."""
        if self.has_extension("GL_NVX_gpu_memory_info") and self.raw.has("glGetIntegerv"):
            kb = ctypes.c_int(0)
            self.raw.glGetIntegerv(GL_GPU_MEMORY_INFO_DEDICATED_VIDMEM_NVX, ctypes.byref(kb))
            return kb.value * 1024 if kb.value > 0 else None
        if self.is_software:
            return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        return None

    def release(self) -> None:
        global _current
        try:
            self.ctx.release()
        finally:
            self._release()
            if self in _live:
                _live.remove(self)
            if _current is self:  # a released current context keeps taking the calls: back to the last live one
                _current = None
                if _live:
                    _live[-1].make_current()


def is_software_renderer(ctx: moderngl.Context) -> bool:
    """Mesa's CPU rasterizers: correct images, but GL timer queries there do not measure GPU
    work (they read near zero or garbage), and there is no GPU clock to ramp up: timings are for
    information only."""
    renderer = (ctx.info.get("GL_RENDERER") or "").lower()
    return any(name in renderer for name in ("llvmpipe", "softpipe", "swrast"))


# The contexts of this process that are not released, oldest first, and the one rayvr made current.
_live: list[GLContext] = []
_current: GLContext | None = None


def _check_version(ctx: moderngl.Context, backend: str) -> None:
    if ctx.version_code < REQUIRED_GL:
        version = ctx.info.get("GL_VERSION")
        ctx.release()
        raise ContextError(f"{backend}: OpenGL {version} is older than the required 4.3 core")


def _egl_library():
    """libEGL with eglGetProcAddress typed."""
    lib = ctypes.util.find_library("EGL")
    if not lib:
        raise ContextError("libEGL not found")
    egl = ctypes.CDLL(lib)
    egl.eglGetProcAddress.restype = ctypes.c_void_p
    egl.eglGetProcAddress.argtypes = [ctypes.c_char_p]
    return egl


def _egl_proc_loader() -> Callable[[str], int | None]:
    egl = _egl_library()
    return lambda name: egl.eglGetProcAddress(name.encode())


# ------------------------------------------------------------------ which EGL device is which GPU
# Ray (like any GPU scheduler) names a worker's GPU through CUDA_VISIBLE_DEVICES; EGL lists its
# devices in its own order (software devices included). EGL_NV_device_cuda says which CUDA device
# an EGL device is, which is what ties the two together.
EGL_EXTENSIONS, EGL_CUDA_DEVICE_NV = 0x3055, 0x323A
EGL_VENDOR, EGL_RENDERER_EXT, EGL_DRM_DEVICE_FILE_EXT = 0x3053, 0x335F, 0x3233  # a device's name, where told
# An explicit EGL device index (rayvr's --device sets it): every headless context of the process takes
# that device, and it wins over the CUDA_VISIBLE_DEVICES mapping.
EGL_DEVICE_ENV = "RAYVR_EGL_DEVICE"


@dataclass(frozen=True)
class EglDevice:
    index: int  # position in eglQueryDevicesEXT's list: moderngl's `device_index`
    extensions: str
    cuda: int | None  # the CUDA device ordinal EGL_NV_device_cuda reports (None: no answer)
    name: str = ""  # EGL_EXT_device_query_name's renderer (and vendor), else its DRM file, else ""

    @property
    def nvidia(self) -> bool:
        return "EGL_NV_device_cuda" in self.extensions.split()

    @property
    def software(self) -> bool:
        return "EGL_MESA_device_software" in self.extensions.split()

    def describe(self) -> str:
        """"1: NVIDIA ... (CUDA device 0)": as rayvr info lists it, the index --device takes."""
        name = self.name or ("a software rasterizer" if self.software else "unnamed")
        return f"{self.index}: {name}" + (f" (CUDA device {self.cuda})" if self.cuda is not None else "")


def egl_devices() -> list[EglDevice]:
    """The EGL devices (EGL_EXT_device_enumeration/_query), in the order moderngl indexes them."""
    egl = _egl_library()
    addr = {n: egl.eglGetProcAddress(n.encode()) for n in
            ("eglQueryDevicesEXT", "eglQueryDeviceStringEXT", "eglQueryDeviceAttribEXT")}
    if not (addr["eglQueryDevicesEXT"] and addr["eglQueryDeviceStringEXT"]):
        raise ContextError("egl: the driver cannot enumerate devices (no EGL_EXT_device_enumeration)")
    vp, ip = ctypes.c_void_p, ctypes.c_int
    query_devices = ctypes.CFUNCTYPE(ctypes.c_uint, ip, ctypes.POINTER(vp), ctypes.POINTER(ip))(addr["eglQueryDevicesEXT"])
    query_string = ctypes.CFUNCTYPE(ctypes.c_char_p, vp, ip)(addr["eglQueryDeviceStringEXT"])
    query_attrib = (ctypes.CFUNCTYPE(ctypes.c_uint, vp, ip, ctypes.POINTER(ctypes.c_ssize_t))(addr["eglQueryDeviceAttribEXT"])
                    if addr["eglQueryDeviceAttribEXT"] else None)
    handles, count = (vp * 64)(), ip(0)
    if not query_devices(64, handles, ctypes.byref(count)):
        raise ContextError("egl: eglQueryDevicesEXT failed")
    out = []
    for i in range(count.value):
        ext = (query_string(handles[i], EGL_EXTENSIONS) or b"").decode(errors="replace")
        value, cuda = ctypes.c_ssize_t(-1), None
        if query_attrib and "EGL_NV_device_cuda" in ext.split() and query_attrib(handles[i], EGL_CUDA_DEVICE_NV,
                                                                               ctypes.byref(value)):
            cuda = int(value.value)
        names = []
        for enum, needs in ((EGL_RENDERER_EXT, "EGL_EXT_device_query_name"), (EGL_VENDOR, "EGL_EXT_device_query_name"),
                            (EGL_DRM_DEVICE_FILE_EXT, "EGL_EXT_device_drm")):
            text = query_string(handles[i], enum) if needs in ext.split() else None
            if text and text.decode(errors="replace") not in names:
                names.append(text.decode(errors="replace"))
        out.append(EglDevice(i, ext, cuda, ", ".join(names[:2])))
    return out


def chosen_egl_device(env=None, check: bool = True) -> int | None:
    """RAYVR_EGL_DEVICE's EGL device index (--device), with `check` one of the devices there are; None unset."""
    env = os.environ if env is None else env
    text = env.get(EGL_DEVICE_ENV, "").strip()
    if not text:
        return None
    try:
        index = int(text)
    except ValueError:
        raise ContextError(f"{EGL_DEVICE_ENV} must be an EGL device index (--device N), got {text!r}") from None
    devices = egl_devices() if check else []
    if check and not 0 <= index < len(devices):
        listed = "; ".join(d.describe() for d in devices) or "none"
        raise ContextError(f"--device {index}: there is no EGL device {index}; the devices are {listed} "
                           f"(rayvr info lists them)")
    return index


def egl_device_for_gpu(devices: list[EglDevice], gpu: str, visible: list[str]) -> int | None:
    """The EGL device index of CUDA device `gpu` (an entry of CUDA_VISIBLE_DEVICES, `visible`).

    Drivers answer EGL_CUDA_DEVICE_NV in one of two ways: with physical ordinals for every NVIDIA
    device, or (when they apply CUDA_VISIBLE_DEVICES) with ordinals among the visible devices only,
    the hidden ones not answering. None when no device speaks EGL_NV_device_cuda (no NVIDIA GPU,
    e.g. llvmpipe): the default device is then the only sensible one."""
    nvidia = [d for d in devices if d.nvidia]
    answered = [d for d in nvidia if d.cuda is not None]
    if not answered:
        return None
    if len(answered) < len(nvidia):  # the driver hides what CUDA_VISIBLE_DEVICES hides
        if gpu not in visible:
            raise ContextError(f"GPU {gpu!r} is not among CUDA_VISIBLE_DEVICES={','.join(visible)}")
        want = visible.index(gpu)
    else:
        try:
            want = int(gpu)
        except ValueError:
            raise ContextError(f"GPU {gpu!r} is not a CUDA ordinal; set {EGL_DEVICE_ENV} to its EGL device index "
                               f"(rayvr info lists them)") from None
    for d in answered:
        if d.cuda == want:
            return d.index
    seen = ", ".join(f"EGL {d.index} = CUDA {d.cuda}" for d in answered)
    raise ContextError(f"no EGL device is CUDA device {want} (GPU {gpu!r}); EGL reports {seen}; "
                       f"set {EGL_DEVICE_ENV} to pick one")


def assigned_egl_device(env=None, devices=None) -> int | None:
    """The EGL device of the GPU this process was given: RAYVR_EGL_DEVICE if set, else the first
    entry of CUDA_VISIBLE_DEVICES (what Ray sets for a worker) mapped through EGL_NV_device_cuda;
    None without either (the driver's default device)."""
    env = os.environ if env is None else env
    if env.get(EGL_DEVICE_ENV, "").strip():
        return chosen_egl_device(env, check=False)  # (the context it makes says if there is no such device)
    visible = [v.strip() for v in env.get("CUDA_VISIBLE_DEVICES", "").split(",") if v.strip()]
    if not visible:
        return None
    return egl_device_for_gpu(egl_devices() if devices is None else devices, visible[0], visible)


def create_egl_context(device_index: int | None = None) -> GLContext:
    """Headless EGL context; `device_index` picks the GPU when there are several."""
    kwargs = {"backend": "egl", "require": REQUIRED_GL}
    if device_index is not None:
        kwargs["device_index"] = int(device_index)
    try:
        ctx = moderngl.create_standalone_context(**kwargs)
    except Exception as exc:  # moderngl raises plain Exception here
        raise ContextError(f"egl: {exc}") from exc
    _check_version(ctx, "egl")
    return GLContext(ctx, "egl", RawGL(_egl_proc_loader()), _activate=ctx.__enter__)


class _OSMesaLoader:
    """The loader object `moderngl.init_context` expects, backed by OSMesaGetProcAddress."""

    def __init__(self, lib):
        self._lib = lib

    def load_opengl_function(self, name: str) -> int:
        return self._lib.OSMesaGetProcAddress(name.encode()) or 0

    def release(self) -> None:
        pass


def create_osmesa_context(size: tuple[int, int] = (16, 16)) -> GLContext:
    """Headless OSMesa (Mesa's software renderer, Debian's libosmesa6) context, 4.5 core."""
    path = ctypes.util.find_library("OSMesa") or "libOSMesa.so.8"
    try:
        lib = ctypes.CDLL(path)
    except OSError as exc:
        raise ContextError(f"osmesa: cannot load libOSMesa ({exc}); on Debian: apt-get install libosmesa6") from exc
    lib.OSMesaCreateContextAttribs.restype = ctypes.c_void_p
    lib.OSMesaCreateContextAttribs.argtypes = [ctypes.POINTER(ctypes.c_int), ctypes.c_void_p]
    lib.OSMesaMakeCurrent.restype = ctypes.c_ubyte
    lib.OSMesaMakeCurrent.argtypes = [ctypes.c_void_p, ctypes.c_void_p, ctypes.c_uint, ctypes.c_int, ctypes.c_int]
    lib.OSMesaGetProcAddress.restype = ctypes.c_void_p
    lib.OSMesaGetProcAddress.argtypes = [ctypes.c_char_p]
    lib.OSMesaDestroyContext.argtypes = [ctypes.c_void_p]
    OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS = 0x22, 0x1908, 0x30
    OSMESA_PROFILE, OSMESA_CORE_PROFILE = 0x33, 0x34
    OSMESA_CONTEXT_MAJOR, OSMESA_CONTEXT_MINOR = 0x36, 0x37
    attrs = (ctypes.c_int * 13)(OSMESA_FORMAT, OSMESA_RGBA, OSMESA_DEPTH_BITS, 24,
                                OSMESA_PROFILE, OSMESA_CORE_PROFILE,
                                OSMESA_CONTEXT_MAJOR, 4, OSMESA_CONTEXT_MINOR, 5, 0, 0, 0)
    handle = lib.OSMesaCreateContextAttribs(attrs, None)
    if not handle:
        raise ContextError("osmesa: OSMesaCreateContextAttribs failed (no 4.5 core profile?)")
    w, h = size
    buffer = ctypes.create_string_buffer(w * h * 4)

    def activate() -> bool:
        return bool(lib.OSMesaMakeCurrent(handle, buffer, GL_UNSIGNED_BYTE, w, h))

    if not activate():
        lib.OSMesaDestroyContext(handle)
        raise ContextError("osmesa: OSMesaMakeCurrent failed")
    try:
        moderngl.init_context(loader=_OSMesaLoader(lib))
        ctx = moderngl.get_context()
    except Exception as exc:
        lib.OSMesaDestroyContext(handle)
        raise ContextError(f"osmesa: {exc}") from exc
    _check_version(ctx, "osmesa")

    def release():
        lib.OSMesaDestroyContext(handle)
        buffer  # keep the colour buffer alive as long as the context

    return GLContext(ctx, "osmesa", RawGL(lambda n: lib.OSMesaGetProcAddress(n.encode())), release, _activate=activate)


def create_context(backend: str | None = None, device_index: int | None = None) -> GLContext:
    """A headless context. `backend` is 'egl', 'osmesa' or None (try each; env RAYVR_GL_BACKEND)."""
    backend = backend or os.environ.get("RAYVR_GL_BACKEND") or None
    # a device asked for by index is an EGL device: no other backend stands in for it
    order = [backend] if backend else (["egl"] if os.environ.get(EGL_DEVICE_ENV, "").strip() else list(HEADLESS_BACKENDS))
    failures = []
    for name in order:
        try:
            if name == "egl":
                return create_egl_context(chosen_egl_device() if device_index is None else device_index)
            if name == "osmesa":
                return create_osmesa_context()
            raise ContextError(f"unknown backend {name!r}; choose one of {', '.join(HEADLESS_BACKENDS)}")
        except ContextError as exc:
            failures.append(f"  - {exc}")
    if len(failures) == 1:  # one backend tried: one line
        raise ContextError(f"no OpenGL 4.3 core context could be made: {failures[0].strip()[2:]}")
    raise ContextError("no OpenGL 4.3 core context could be made:\n" + "\n".join(failures))


def import_glfw():
    """The glfw module, or a ContextError saying it is missing (a core dependency a bare
    PYTHONPATH install can lack) instead of an ImportError's traceback."""
    try:
        import glfw
    except ImportError as exc:
        raise ContextError(f"glfw: the Python package cannot be imported ({exc}); pip install glfw") from None
    return glfw


def create_window_context(size=(1280, 720), title="rayvr", visible=True, vsync=True):
    """A glfw window with a 4.3 core context; returns (window, GLContext)."""
    glfw = import_glfw()

    # GLFW's own words go into the one error line, not into a Python warning printed beside it;
    # once the window is open, later ones are logged.
    said = []
    glfw.set_error_callback(lambda code, text: said.append(text.decode(errors="replace") if isinstance(text, bytes)
                                                           else str(text)))

    def why() -> str:
        return f" ({'; '.join(said)})" if said else ""
    if not glfw.init():
        raise ContextError(f"glfw: init failed{why()}: set DISPLAY or run under Xvfb")
    glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, 4)
    glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, 3)
    glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
    glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
    glfw.window_hint(glfw.VISIBLE, visible)
    window = glfw.create_window(int(size[0]), int(size[1]), title, None, None)
    if not window:
        glfw.terminate()
        raise ContextError(f"glfw: could not open a window with an OpenGL 4.3 core context{why()}")
    glfw.set_error_callback(lambda code, text: logging.getLogger(__name__).warning("glfw: %s", text))
    glfw.make_context_current(window)
    glfw.swap_interval(1 if vsync else 0)
    try:
        ctx = moderngl.create_context(require=REQUIRED_GL)
    except Exception as exc:
        glfw.destroy_window(window)
        raise ContextError(f"glfw: {exc}") from exc

    def release():
        glfw.destroy_window(window)

    return window, GLContext(ctx, "glfw", RawGL(lambda n: glfw.get_proc_address(n)), release,
                             _activate=lambda: glfw.make_context_current(window))
