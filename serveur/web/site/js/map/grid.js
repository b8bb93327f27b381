// The occupancy grid of the `map` topic as an image the canvas can draw.
//
// The grid is W*H signed bytes, row 0 at the LOWEST y (ROS OccupancyGrid order): -1 unknown,
// 0 free .. 100 occupied. We keep that row order in the image and let the map view draw it
// with a y-up transform, which is what flips it right way up (see view.js).

import { t } from "../i18n.js";

const UNKNOWN = [200, 204, 210];
const FREE = [255, 255, 255];
const OCCUPIED = [31, 38, 48];

/** The grid the right way up (row 0 at the top), for a canvas drawn in pixels, without the map
 *  view's y-up transform (the owner's map pictures in the Restaurant tab). */
export function uprightGrid(map) {
  const canvas = document.createElement("canvas");
  canvas.width = map.width;
  canvas.height = map.height;
  const ctx = canvas.getContext("2d");
  ctx.setTransform(1, 0, 0, -1, 0, map.height); // the grid's rows go up
  ctx.drawImage(decodeGrid(map), 0, 0);
  return canvas;
}

export function decodeGrid(map) {
  const { width, height } = map;
  const raw = atob(map.data);
  if (raw.length !== width * height) {
    throw new Error(t("map.badGrid", { cells: raw.length, width, height }));
  }
  const canvas = document.createElement("canvas");
  canvas.width = width;
  canvas.height = height;
  const ctx = canvas.getContext("2d");
  const image = ctx.createImageData(width, height);
  const px = image.data;
  for (let i = 0; i < raw.length; i++) {
    let v = raw.charCodeAt(i);
    if (v > 127) v -= 256; // int8
    let rgb;
    if (v < 0) rgb = UNKNOWN;
    else {
      const t = Math.min(v, 100) / 100;
      rgb = [0, 1, 2].map((k) => Math.round(FREE[k] + (OCCUPIED[k] - FREE[k]) * t));
    }
    px[i * 4] = rgb[0];
    px[i * 4 + 1] = rgb[1];
    px[i * 4 + 2] = rgb[2];
    px[i * 4 + 3] = 255;
  }
  ctx.putImageData(image, 0, 0);
  return canvas;
}
