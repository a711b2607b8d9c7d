// What of the panel a person cannot read whole: the check behind the panel's layout tests.

/** The panel's titles, labels, choices, buttons and texts that do not show whole at the page's
 *  size, each as `text: why`. A label shows whole when its own box clips nothing of it (its
 *  scroll size is within its client size: no cut-off end, no hidden second line) and it lies
 *  inside the panel, which lies inside the window. */
export function clippedLabels(page) {
  return page.evaluate(() => {
    const panel = document.querySelector('#panel .lil-root');
    if (!panel) return ['no panel'];
    const edge = panel.getBoundingClientRect();
    const found = [];
    if (edge.left < 0 || edge.right > window.innerWidth) found.push(`the panel: outside the window`);
    const selector = '.lil-title, .lil-name, .lil-display, .panel-text, button, input[type=text], input[type=number]';
    for (const el of panel.querySelectorAll(selector)) {
      const text = el instanceof HTMLInputElement ? el.value : (el.textContent ?? '').trim();
      const box = el.getBoundingClientRect();
      if (!text || box.width === 0) continue; // empty, or in a closed folder
      const why = [];
      if (el.scrollWidth > el.clientWidth + 1) why.push(`${el.scrollWidth - el.clientWidth} px cut off`);
      if (el.scrollHeight > el.clientHeight + 1) why.push('a line hidden');
      if (box.left < edge.left - 0.5 || box.right > edge.right + 0.5) why.push('outside the panel');
      if (why.length > 0) found.push(`${text}: ${why.join(', ')}`);
    }
    return found;
  });
}

/** The panel's list of worlds (the choice in its World folder): its options' texts, the
 *  selected one's, and what it shows. */
export function worldList(page) {
  return page.evaluate(() => {
    const folders = Array.from(document.querySelectorAll('#panel .lil-gui'));
    const world = folders.find((f) => f.querySelector(':scope > .lil-title')?.textContent === 'World');
    const select = world?.querySelector('select');
    if (!select) return undefined;
    return {
      options: Array.from(select.options, (o) => o.text),
      selected: select.selectedIndex >= 0 ? select.options[select.selectedIndex].text : undefined,
      shown: select.parentElement.querySelector('.lil-display')?.textContent ?? '',
    };
  });
}
