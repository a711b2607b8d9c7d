// What `jello view` serves the page (config.json), and the worlds the panel lists from it: the
// user's own file given on the command line (when it is not one of the examples), then the
// shipped examples.

/** What `jello view` tells the page (config.json). */
export interface ServerConfig {
  /** URL of the world given on the command line, its file name, and whether that file is one of
   *  the examples (then it is listed as that example, not as the user's own). */
  world?: { url: string; name: string; example?: boolean };
  /** File names of the example worlds and scenes, served under `examples/`. */
  examples: string[];
}

/** A world the panel lists: fetched from `url`, loaded as `name`, shown as `label`. */
export interface ServedWorld {
  url: string;
  name: string;
  label: string;
}

export function exampleUrl(name: string): string {
  return `examples/${encodeURIComponent(name)}`;
}

/** The worlds to list: the user's own file first (named as theirs, or as the only file served
 *  when there are no examples), then the examples. */
export function servedWorlds(config: ServerConfig): ServedWorld[] {
  const examples = config.examples.map((name) => ({ url: exampleUrl(name), name, label: name }));
  const given = config.world;
  if (!given || (given.example && config.examples.includes(given.name))) return examples;
  const whose = examples.length > 0 ? 'your file' : 'the only file served';
  return [{ url: given.url, name: given.name, label: `${given.name} (${whose})` }, ...examples];
}

/** The URL under which the world given on the command line is listed: an example's own URL
 *  when it is that example's file. */
export function listedUrl(given: NonNullable<ServerConfig['world']>, config: ServerConfig): string {
  return given.example && config.examples.includes(given.name) ? exampleUrl(given.name) : given.url;
}
