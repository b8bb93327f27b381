// The Restaurant tab's files: a picture the owner picked, decoded here, and where a pointer is
// on it; a file saved on the device; and a file sent to the server in parts (`site upload`, then
// `upload_part`s: a message is at most 64 KiB), for the map, the floor plan and backups. Each part waits for its answer, so a
// refused part (a reconnect in between) stops the upload with the server's reason; a part the
// rate limit refused is sent again after the wait the server names.

/** Bytes -> base64, in slices (String.fromCharCode takes only so many arguments). */
function base64(bytes) {
  let s = "";
  for (let i = 0; i < bytes.length; i += 0x8000) s += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(s);
}

const pause = (seconds) => new Promise((resolve) => setTimeout(resolve, Math.ceil(seconds * 1000)));

/** Upload `file` as `kind`; `progress(percent)` after each part; resolves with the upload's id. */
export async function sendFile(conn, file, kind, progress = () => {}) {
  const bytes = new Uint8Array(await file.arrayBuffer());
  const up = (await conn.request({ clientmsg: "site", action: "upload", kind, name: file.name, size: bytes.length })).upload;
  for (let offset = 0; offset < bytes.length; offset += up.part) {
    const msg = { clientmsg: "site", action: "upload_part", upload: up.id, offset, data: base64(bytes.subarray(offset, offset + up.part)) };
    for (;;) {
      try {
        await conn.request(msg);
        break;
      } catch (err) {
        if (err.code !== "rate_limited") throw err;
        await pause((err.details && err.details.wait) || 1);
      }
    }
    progress(Math.floor((100 * Math.min(bytes.length, offset + up.part)) / bytes.length));
  }
  return up.id;
}

/** A pointer's position on `canvas` in the canvas's own pixels (a tenth of a pixel). */
export function pixelAt(canvas, e) {
  const r = canvas.getBoundingClientRect();
  return [((e.clientX - r.left) * canvas.width) / r.width, ((e.clientY - r.top) * canvas.height) / r.height].map((v) => Math.round(v * 10) / 10);
}

/** Let the browser save what `href` points at (a download link or an object URL) as `name`. */
export function saveAs(href, name = "") {
  const a = document.createElement("a");
  a.href = href;
  a.download = name;
  a.hidden = true;
  document.body.append(a);
  a.click();
  a.remove();
}

/** The picture in `file` as the browser decodes it (a floor plan shown on the page: the server
 *  never decodes pictures), or null when it is not one. */
export async function decodeImage(file) {
  const img = new Image();
  img.src = URL.createObjectURL(file);
  try {
    await img.decode();
    return img;
  } catch {
    URL.revokeObjectURL(img.src);
    return null;
  }
}
