// Pixel checks on what Chromium really composited: Playwright screenshots of the canvas, decoded
// in the page itself (createImageBitmap), so no PNG library is needed.

/** Hides the page's overlays (readout text, panel, banners) so screenshots show only the canvas;
 *  resolves to a function that shows them again. */
export async function hideOverlays(page) {
  const style = await page.addStyleTag({ content: '#hud, #panel, #banners { visibility: hidden !important; }' });
  return () => style.evaluate((e) => e.remove());
}

/** A PNG screenshot of the canvas. */
export function shot(page) {
  return page.locator('#view').screenshot();
}

/** Decodes PNGs in the page and returns, for `a`: the number of jello-red pixels and of
 *  non-background pixels; and, when `b` is given, how many pixels differ between them. */
export async function analyse(page, a, b) {
  return page.evaluate(
    async ([a64, b64]) => {
      const decode = async (s) => {
        const bytes = Uint8Array.from(atob(s), (c) => c.charCodeAt(0));
        const bitmap = await createImageBitmap(new Blob([bytes], { type: 'image/png' }));
        const canvas = new OffscreenCanvas(bitmap.width, bitmap.height);
        const ctx = canvas.getContext('2d');
        ctx.drawImage(bitmap, 0, 0);
        return ctx.getImageData(0, 0, bitmap.width, bitmap.height).data;
      };
      const pa = await decode(a64);
      let red = 0;
      let drawn = 0;
      const [br, bg, bb] = [0x16, 0x18, 0x1d]; // the background colour
      for (let i = 0; i < pa.length; i += 4) {
        const [r, g, b] = [pa[i], pa[i + 1], pa[i + 2]];
        if (r > 100 && r > 1.5 * g && r > 1.2 * b) red++;
        if (Math.abs(r - br) + Math.abs(g - bg) + Math.abs(b - bb) > 30) drawn++;
      }
      let differing;
      if (b64) {
        const pb = await decode(b64);
        differing = 0;
        for (let i = 0; i < pa.length; i += 4) {
          const d = Math.abs(pa[i] - pb[i]) + Math.abs(pa[i + 1] - pb[i + 1]) + Math.abs(pa[i + 2] - pb[i + 2]);
          if (d > 24) differing++;
        }
      }
      return { pixels: pa.length / 4, red, drawn, differing };
    },
    [a.toString('base64'), b?.toString('base64')],
  );
}

/** Pixels that differ between two screenshots. */
export async function difference(page, a, b) {
  return (await analyse(page, a, b)).differing;
}
