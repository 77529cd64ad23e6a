// Plans the demo road through the generated types and openapi-fetch, against a running server:
// GET /v1/demo, POST /v1/plan with it, then checks the answer; also checks that a broken request
// gets a 422 in the API's error shape. Exits 1 on any failed check.
//
//   node build/plan-demo.js http://127.0.0.1:8000     (or KAPPA_URL=… node build/plan-demo.js)
import createClient from "openapi-fetch";

import type { components, paths } from "./schema.js";

type PlanningRequest = components["schemas"]["PlanningRequest"];
type PlanResponse = components["schemas"]["PlanResponse"];
/** What the checks read of the request (openapi-fetch 0.17 hands tuples such as [x, y] back as
 * number[], so the demo as received is not a `PlanningRequest` to the letter). */
type PlanChecked = Pick<PlanningRequest, "ego" | "options">;

const baseUrl = process.argv[2] ?? process.env["KAPPA_URL"] ?? "http://127.0.0.1:8000";
const client = createClient<paths>({ baseUrl });
const failures: string[] = [];

function check(ok: boolean, what: string): void {
    if (!ok) failures.push(what);
}

/** The checks every plan of the demo must pass (failures go to `failures`). */
function checkPlan(request: PlanChecked, plan: PlanResponse): void {
    const dt = request.options?.dt;
    const horizon = request.options?.horizon_time;
    check(dt !== undefined && horizon !== undefined, "the demo states options.dt and options.horizon_time");
    check(["ok", "stopped", "fallback"].includes(plan.status), `status ${plan.status} is a known status`);
    check(plan.status === "ok", `the demo plans with status ok (got ${plan.status}: ${plan.message})`);
    const points = plan.trajectory;
    const first = points[0];
    if (first === undefined) {
        check(false, "the trajectory is not empty");
        return;
    }
    check(Math.abs(first.t) <= 1e-9, `the first point is at t = 0 (got ${first.t})`);
    check(
        Math.hypot(first.x - request.ego.x, first.y - request.ego.y) <= 1e-6,
        `the first point is the ego (${first.x}, ${first.y}) vs (${request.ego.x}, ${request.ego.y})`,
    );
    points.forEach((point, i) => {
        check(Number.isFinite(point.v) && point.v >= 0, `v[${i}] = ${point.v} is finite and ≥ 0`);
        const previous = points[i - 1];
        if (previous !== undefined && dt !== undefined) {
            check(Math.abs(point.t - previous.t - dt) <= 1e-9, `t[${i}] − t[${i - 1}] = dt (${point.t} after ${previous.t})`);
        }
    });
    const last = points[points.length - 1];
    if (last !== undefined && horizon !== undefined) {
        check(last.t <= horizon + 1e-9, `the trajectory ends within the horizon (${last.t} ≤ ${horizon})`);
    }
}

async function main(): Promise<void> {
    const demo = await client.GET("/v1/demo");
    if (demo.data === undefined) {
        throw new Error(`GET /v1/demo answered ${demo.response.status}`);
    }
    const request = demo.data;

    const answer = await client.POST("/v1/plan", { body: request });
    if (answer.error !== undefined) {
        throw new Error(`POST /v1/plan answered ${answer.response.status}: ${answer.error.error.message}`);
    }
    checkPlan(request, answer.data);
    console.log(
        `plan: status ${answer.data.status}, ${answer.data.trajectory.length} points, ` +
            `${answer.data.diagnostics.timing_ms.total.toFixed(1)} ms`,
    );

    // A request with a one-point reference line: a 422 whose body is the typed ErrorResponse.
    const broken = await client.POST("/v1/frenet", { body: { reference_line: [[0, 0]], points: [[1, 2]] } });
    check(broken.response.status === 422, `a broken request gets 422 (got ${broken.response.status})`);
    check(broken.error?.error.code === "invalid_request", `its error code is invalid_request`);
    check(
        broken.error?.error.details.some((detail) => detail.field === "reference_line") === true,
        "its details name reference_line",
    );

    if (failures.length > 0) {
        console.error(`FAILED ${failures.length} check(s):\n  ${failures.join("\n  ")}`);
        process.exit(1);
    }
    console.log("typescript client: all checks passed");
}

main().catch((error: unknown) => {
    console.error(error);
    process.exit(1);
});
