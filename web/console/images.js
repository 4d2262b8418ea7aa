/* The live pictures: camera/image_raw/compressed and thermal/image_raw/compressed (JPEG
   sensor_msgs/CompressedImage) drawn on canvases, the hottest point marked, and a click on the visible
   picture turning the head there (preset_rotate). Subscribed with CBOR compression, so the JPEG
   arrives as bytes (no base64), and queue_length 1, so a slow link gets the newest frame rather than
   a backlog; a frame arriving while the browser still decodes the previous one replaces the one
   waiting (decode.newestOnly). */
import { t } from './i18n.js';
import { newestOnly } from './decode.js';
import { publish, subscribe } from './link.js';
import { $, canvasPoint, log } from './ui.js';

export const VIDEO = { compression: 'cbor', queue_length: 1 };   // the recommended video subscription
let hottest = null;   // thermal/hottest: {x, y, temperature}

function bytesOf(data) {
  if (data instanceof Uint8Array) return data;
  if (typeof data === 'string') {   // JSON encoding: base64
    const text = atob(data);
    const out = new Uint8Array(text.length);
    for (let i = 0; i < text.length; i++) out[i] = text.charCodeAt(i);
    return out;
  }
  return Uint8Array.from(data);
}

function drawMarker(ctx, marker) {
  ctx.strokeStyle = '#00e5ff';
  ctx.lineWidth = 2;
  ctx.beginPath();
  ctx.arc(marker.x, marker.y, 8, 0, 2 * Math.PI);
  ctx.moveTo(marker.x - 14, marker.y);
  ctx.lineTo(marker.x + 14, marker.y);
  ctx.moveTo(marker.x, marker.y - 14);
  ctx.lineTo(marker.x, marker.y + 14);
  ctx.stroke();
}

/** Draws a JPEG CompressedImage onto a canvas (resized to the picture), newest frame first. */
function jpegView(canvas, marker) {
  return newestOnly((msg) => createImageBitmap(new Blob([bytesOf(msg.data)], { type: 'image/jpeg' }))
    .then((bitmap) => {
      if (canvas.width !== bitmap.width || canvas.height !== bitmap.height) {
        canvas.width = bitmap.width;
        canvas.height = bitmap.height;
      }
      const ctx = canvas.getContext('2d');
      ctx.drawImage(bitmap, 0, 0);
      bitmap.close();
      window.consoleFrames[canvas.id] += 1;
      const mark = marker();
      if (mark) drawMarker(ctx, mark);
    }, (err) => log(canvas.id + ': ' + t('a frame could not be decoded') + ': ' + err, true)));
}

function onHottest(msg) {
  try {
    hottest = JSON.parse(msg.data);
    $('thermal-caption').textContent = t('thermal: hottest {temperature} °C at ({x}, {y})',
      { temperature: hottest.temperature.toFixed(1), x: hottest.x, y: hottest.y });
  } catch (err) {
    log('thermal/hottest ' + t('unreadable') + ': ' + err, true);
  }
}

export function init() {
  window.consoleFrames = { picture: 0, thermal: 0 };   // live pictures drawn, for the browser tests
  $('picture').addEventListener('click', (event) => {
    const canvas = $('picture');
    const [x, y] = canvasPoint(canvas, event);
    publish('preset_rotate', 'inspection_robot/PresetRotate', { width: canvas.width, height: canvas.height,
      delta_x: Math.round(x - canvas.width / 2), delta_y: Math.round(canvas.height / 2 - y) });
  });
  subscribe('camera/image_raw/compressed', 'sensor_msgs/CompressedImage', VIDEO, jpegView($('picture'), () => null));
  subscribe('thermal/image_raw/compressed', 'sensor_msgs/CompressedImage', VIDEO, jpegView($('thermal'), () => hottest));
  subscribe('thermal/hottest', 'inspection_robot/GeneralTopic', { queue_length: 1 }, onHottest);
}
