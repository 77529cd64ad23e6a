// Talking to the service (same origin, paths relative to the page so that a prefix works) and
// reading documents from URLs or files. Every failure becomes an ApiError with the service's error
// shape {code, message, details: [{field, message}]}: HTTP errors, network errors, bad JSON.

export class ApiError extends Error {
  constructor({ status = 0, code, message, details = [], url = "" }) {
    super(message);
    this.status = status;
    this.code = code;
    this.details = details;
    this.url = url;
  }
}

let apiKey = "";

/** The key sent as `Authorization: Bearer KEY` to the service (kept in this page only). */
export function setApiKey(key) {
  apiKey = key.trim();
}

function sameOrigin(url) {
  return new URL(url, document.baseURI).origin === window.location.origin;
}

function headers(url, extra = {}) {
  const out = { Accept: "application/json", ...extra };
  if (apiKey && sameOrigin(url)) out.Authorization = `Bearer ${apiKey}`; // never to another origin
  return out;
}

async function errorOf(response, url) {
  const text = await response.text().catch(() => "");
  let body = null;
  try {
    body = JSON.parse(text);
  } catch {
    body = null;
  }
  const err = body && typeof body === "object" ? body.error : null;
  if (err && typeof err.code === "string") {
    const details = Array.isArray(err.details)
      ? err.details.map((d) => ({ field: String(d.field ?? ""), message: String(d.message ?? "") }))
      : [];
    return new ApiError({ status: response.status, code: err.code, message: String(err.message ?? ""), details, url });
  }
  const snippet = text.trim().slice(0, 300);
  return new ApiError({
    status: response.status,
    code: `http_${response.status}`,
    message: `${response.status} ${response.statusText}${snippet ? `: ${snippet}` : ""}`,
    url,
  });
}

async function send(url, init) {
  let response;
  try {
    response = await fetch(url, init);
  } catch (exc) {
    if (exc && exc.name === "AbortError") throw exc;
    throw new ApiError({
      code: "network_error",
      message: `Could not reach ${new URL(url, document.baseURI).href}: ${exc && exc.message ? exc.message : exc}`,
      url,
    });
  }
  if (!response.ok) throw await errorOf(response, url);
  return response;
}

/** POST a JSON body to the service's `path` (e.g. "v1/plan") and return the answer's JSON. */
export async function post(path, body, signal) {
  const url = new URL(path, document.baseURI).href;
  const response = await send(url, {
    method: "POST",
    headers: headers(url, { "Content-Type": "application/json" }),
    body: JSON.stringify(body),
    signal,
  });
  return response.json();
}

/** GET a JSON document from the service or any URL (the key only to the service's own origin). */
export async function getJson(path, signal) {
  const url = new URL(path, document.baseURI).href;
  const response = await send(url, { headers: headers(url), signal });
  return parseDocument(await response.arrayBuffer(), url);
}

/** The JSON of bytes that may be gzip-compressed (a run file), as a document. */
export async function parseDocument(buffer, where) {
  let bytes = new Uint8Array(buffer);
  if (bytes.length >= 2 && bytes[0] === 0x1f && bytes[1] === 0x8b) {
    try {
      const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
      bytes = new Uint8Array(await new Response(stream).arrayBuffer());
    } catch (exc) {
      throw new ApiError({ code: "invalid_gzip", message: `${where} is not valid gzip: ${exc.message}` });
    }
  }
  return parseJson(new TextDecoder().decode(bytes), where);
}

/** JSON.parse with an error that says where (line and column). */
export function parseJson(text, where) {
  try {
    return JSON.parse(text);
  } catch (exc) {
    const match = /position (\d+)/.exec(exc.message);
    let at = "";
    if (match) {
      const upto = text.slice(0, Number(match[1]));
      const line = upto.split("\n").length;
      at = ` (line ${line}, column ${upto.length - upto.lastIndexOf("\n")})`;
    }
    throw new ApiError({ code: "invalid_json", message: `${where} is not JSON${at}: ${exc.message}` });
  }
}
