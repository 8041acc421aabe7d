// The runtime beside ACL 2.1, measured the way ACL's decompression benchmark measures itself: one whole pose per
// call (every joint's local rotation and translation, as ACL's decompress_tracks writes them; mcb-rot:
// mcbrot_sample_pose), forward playback, backward playback and random access, each with a warm cache (the clip and the
// context stay in the CPU caches) and a cold one (a buffer larger than the last-level cache is written before a
// timed pose, outside the timing; 48 poses spread over each clip's order are timed so, the others played untimed).
// Thread CPU time, one core.
//
//   bench_vs_acl MANIFEST [REPEATS] [--sample] [--pose FRAME]
//
// MANIFEST: one clip per line, "mcb_stream_path acl_buffer_path" (the .mcb stream of mcb-rot and ACL's
// compressed_tracks buffer of the same clip); blank lines are skipped. Prints one line per clip and decoder:
//   decoder clip frames joints stream_bytes resident_bytes open_us fwd_warm fwd_cold bwd_warm bwd_cold rnd_warm
//   rnd_cold   (the last six in microseconds per pose, medians over REPEATS runs)
// resident_bytes: what the decoder keeps while it samples: the stream (mcb-rot: the whole .mcb; ACL: its buffer)
// plus the context (mcb-rot: mcbrot_context_size; ACL: sizeof its decompression_context).
// --sample: one more line per clip, decoder "mcb-rot-sample", timing mcbrot_sample (rotations and the root's
// translation only, no joint translations) on the same context, taking turns with mcbrot_sample_pose repeat by
// repeat: what the whole pose costs beside it.
// --pose FRAME: no timing; each clip's pose at FRAME (nearest, clamped to the clip), both decoders, one line per
// joint: "pose decoder clip frame joint qx qy qz qw tx ty tz" (%.17g; ACL's float32 values widened).
// A manifest line that is not two readable files, or a stream a decoder refuses, is one line on stderr naming the
// manifest line or the file; the exit status is then 2 (a bad manifest: nothing is timed) or 1 (a clip refused: ACL
// is not timed on it either, the other clips still run).
//
// Built by mocapbench/benchmarks/runtime.py (g++ -O2, ACL's SSE4.1 minimum, the runtime compiled as C with the same
// flags); standard library, ACL and rtm (header-only) only.

#include <acl/core/ansi_allocator.h>
#include <acl/core/compressed_tracks.h>
#include <acl/decompression/decompress.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <string>
#include <vector>

extern "C" {
#include "mcbrot.h"
}

namespace
{
	double thread_seconds()
	{
		timespec now{};
		clock_gettime(CLOCK_THREAD_CPUTIME_ID, &now);
		return double(now.tv_sec) + 1e-9 * double(now.tv_nsec);
	}

	std::vector<uint8_t> read_file(const char* path)
	{
		std::vector<uint8_t> data;
		FILE* file = std::fopen(path, "rb");
		if (!file)
			return data;
		std::fseek(file, 0, SEEK_END);
		long size = std::ftell(file);
		std::fseek(file, 0, SEEK_SET);
		data.resize(size_t(size));
		if (size > 0 && std::fread(data.data(), 1, size_t(size), file) != size_t(size))
			data.clear();
		std::fclose(file);
		return data;
	}

	// Written between poses in cold mode: larger than the last-level cache of the machines we run on (32 MiB).
	std::vector<uint8_t> g_flush(32u << 20);
	// Poses timed per clip and mode with a cold cache (spread evenly over the mode's order): each costs a flush.
	constexpr uint32_t k_cold_poses = 48;
	volatile uint8_t g_sink;

	void flush_caches()
	{
		for (size_t i = 0; i < g_flush.size(); i += 64)
			g_flush[i] = uint8_t(g_flush[i] + 1);
		g_sink = g_flush[g_flush.size() / 2];
	}

	struct pose_writer final : public acl::track_writer
	{
		float* rotations;
		float* translations;
		void RTM_SIMD_CALL write_rotation(uint32_t track_index, rtm::quatf_arg0 rotation)
		{
			rtm::quat_store(rotation, rotations + 4 * track_index);
		}
		void RTM_SIMD_CALL write_translation(uint32_t track_index, rtm::vector4f_arg0 translation)
		{
			rtm::vector_store3(translation, translations + 3 * track_index);
		}
		void RTM_SIMD_CALL write_scale(uint32_t, rtm::vector4f_arg0) {}
	};

	// The frame orders of the three modes.
	std::vector<uint32_t> order_of(int mode, uint32_t frames)
	{
		std::vector<uint32_t> order(frames);
		for (uint32_t i = 0; i < frames; ++i)
			order[i] = mode == 1 ? frames - 1 - i : i;
		if (mode == 2)
		{
			uint64_t state = 0x9e3779b97f4a7c15ull;
			for (uint32_t i = frames; i > 1; --i)
			{
				state = state * 6364136223846793005ull + 1442695040888963407ull;
				std::swap(order[i - 1], order[uint32_t((state >> 33) % i)]);
			}
		}
		return order;
	}

	double median(std::vector<double> values)
	{
		std::sort(values.begin(), values.end());
		return values[values.size() / 2];
	}

	// Microseconds per pose of `sample(frame)` over the order of `mode`, warm or cold, median of `repeats`.
	template<class Sample>
	double time_mode(Sample&& sample, uint32_t frames, int mode, bool cold, int repeats)
	{
		const std::vector<uint32_t> order = order_of(mode, frames);
		std::vector<double> runs;
		for (int r = 0; r < repeats; ++r)
		{
			double total = 0.0;
			if (cold)
			{
				const uint32_t every = std::max<uint32_t>(1, frames / k_cold_poses);
				uint32_t timed = 0;
				for (uint32_t i = 0; i < frames; ++i)
				{
					if (i % every != 0)
					{
						sample(order[i]);  // untimed: playback goes on (a forward player's chunk stays decoded)
						continue;
					}
					flush_caches();
					const double start = thread_seconds();
					sample(order[i]);
					total += thread_seconds() - start;
					++timed;
				}
				runs.push_back(1e6 * total / double(timed));
				continue;
			}
			else
			{
				for (uint32_t frame : order)  // one untimed pass: the caches warm
					sample(frame);
				const double start = thread_seconds();
				for (uint32_t frame : order)
					sample(frame);
				total = thread_seconds() - start;
			}
			runs.push_back(1e6 * total / double(frames));
		}
		return median(runs);
	}

	void report(const char* decoder, const char* clip, uint32_t frames, uint32_t joints, size_t stream_bytes,
		size_t resident, double open_us, const double* modes)
	{
		std::printf("%s %s %u %u %zu %zu %.3f %.4f %.4f %.4f %.4f %.4f %.4f\n", decoder, clip, frames, joints,
			stream_bytes, resident, open_us, modes[0], modes[1], modes[2], modes[3], modes[4], modes[5]);
		std::fflush(stdout);
	}

	struct options
	{
		int repeats = 3;
		bool sample = false;  // also time mcbrot_sample (rotations and root only): "mcb-rot-sample"
		long pose = -1;       // >= 0: print the pose at this frame instead of timing
	};

	// One line per joint: the pose a decoder gave at `frame` (rotations x, y, z, w; translations cm).
	template<class Real>
	void print_pose(const char* decoder, const char* clip, uint32_t frame, uint32_t joints, const Real* rotations,
		const Real* translations)
	{
		for (uint32_t j = 0; j < joints; ++j)
		{
			const Real* q = rotations + 4 * size_t(j);
			const Real* t = translations + 3 * size_t(j);
			std::printf("pose %s %s %u %u %.17g %.17g %.17g %.17g %.17g %.17g %.17g\n", decoder, clip, frame, j,
				double(q[0]), double(q[1]), double(q[2]), double(q[3]), double(t[0]), double(t[1]), double(t[2]));
		}
		std::fflush(stdout);
	}

	uint32_t pose_frame(const options& opts, uint32_t frames)
	{
		return uint32_t(std::min<long>(opts.pose, long(frames) - 1));
	}

	int bench_mcbrot(const char* path, const options& opts)
	{
		std::vector<uint8_t> stream = read_file(path);
		size_t size = 0;
		char message[256];
		if (mcbrot_context_size(stream.data(), stream.size(), &size, message, sizeof message) != MCBROT_OK)
		{
			std::fprintf(stderr, "%s: %s\n", path, message);
			return 1;
		}
		void* context = std::aligned_alloc(16, (size + 15) & ~size_t(15));
		std::vector<double> opens;
		for (int r = 0; r < std::max(opts.repeats, 5); ++r)
		{
			const double start = thread_seconds();
			const int status = mcbrot_open(context, size, stream.data(), stream.size());
			opens.push_back(1e6 * (thread_seconds() - start));
			if (status != MCBROT_OK)
			{
				std::fprintf(stderr, "%s: %s\n", path, mcbrot_message(context));
				std::free(context);
				return 1;
			}
		}
		mcbrot_clip_info info;
		mcbrot_info(context, &info);
		// The whole local pose, as ACL's writer gets it: every joint's rotation and translation.
		std::vector<double> rotations(4 * size_t(info.num_joints)), translations(3 * size_t(info.num_joints));
		const uint32_t first = opts.pose >= 0 ? pose_frame(opts, info.num_frames) : 0;
		if (mcbrot_sample_pose(context, double(first) / info.fps, MCBROT_NEAREST, rotations.data(),
			translations.data()) != MCBROT_OK)
		{
			std::fprintf(stderr, "%s: %s\n", path, mcbrot_message(context));
			std::free(context);
			return 1;
		}
		if (opts.pose >= 0)
		{
			print_pose("mcb-rot", path, first, info.num_joints, rotations.data(), translations.data());
			std::free(context);
			return 0;
		}
		double checksum = 0.0;
		auto sample_pose = [&](uint32_t frame) {
			mcbrot_sample_pose(context, double(frame) / info.fps, MCBROT_NEAREST, rotations.data(),
				translations.data());
			checksum += rotations[0] + translations[0];
		};
		double root[3];
		auto sample = [&](uint32_t frame) {
			mcbrot_sample(context, double(frame) / info.fps, MCBROT_NEAREST, rotations.data(), root);
			checksum += rotations[0] + root[0];
		};
		double modes[6], sampled[6];
		for (int mode = 0; mode < 3; ++mode)
			for (int cold = 0; cold < 2; ++cold)
			{
				if (!opts.sample)
				{
					modes[2 * mode + cold] = time_mode(sample_pose, info.num_frames, mode, cold != 0, opts.repeats);
					continue;
				}
				// Side by side: the two calls take turns, one repeat each, so that both see the same load.
				std::vector<double> pose_runs, sample_runs;
				for (int r = 0; r < opts.repeats; ++r)
				{
					pose_runs.push_back(time_mode(sample_pose, info.num_frames, mode, cold != 0, 1));
					sample_runs.push_back(time_mode(sample, info.num_frames, mode, cold != 0, 1));
				}
				modes[2 * mode + cold] = median(pose_runs);
				sampled[2 * mode + cold] = median(sample_runs);
			}
		report("mcb-rot", path, info.num_frames, info.num_joints, stream.size(), stream.size() + size, median(opens),
			modes);
		if (opts.sample)
			report("mcb-rot-sample", path, info.num_frames, info.num_joints, stream.size(), stream.size() + size,
				median(opens), sampled);
		std::free(context);
		return checksum == checksum ? 0 : 1;
	}

	int bench_acl(const char* path, const char* clip, const options& opts)
	{
		std::vector<uint8_t> file = read_file(path);
		if (file.size() < 64)
		{
			std::fprintf(stderr, "%s: not an ACL buffer (%zu bytes)\n", path, file.size());
			return 1;
		}
		void* memory = std::aligned_alloc(16, (file.size() + 15) & ~size_t(15));
		std::memcpy(memory, file.data(), file.size());
		const acl::compressed_tracks* tracks = static_cast<const acl::compressed_tracks*>(memory);
		const acl::error_result invalid = tracks->is_valid(true);
		if (invalid.any())
		{
			std::fprintf(stderr, "%s: invalid ACL buffer (%s)\n", path, invalid.c_str());
			std::free(memory);
			return 1;
		}
		acl::decompression_context<acl::default_transform_decompression_settings> context;
		std::vector<double> opens;
		for (int r = 0; r < std::max(opts.repeats, 5); ++r)
		{
			const double start = thread_seconds();
			context.initialize(*tracks);
			opens.push_back(1e6 * (thread_seconds() - start));
		}
		const uint32_t joints = tracks->get_num_tracks(), frames = tracks->get_num_samples_per_track();
		const float rate = tracks->get_sample_rate();
		std::vector<float> rotations(4 * size_t(joints)), translations(3 * size_t(joints));
		pose_writer writer;
		writer.rotations = rotations.data();
		writer.translations = translations.data();
		double checksum = 0.0;
		auto sample = [&](uint32_t frame) {
			context.seek(float(frame) / rate, acl::sample_rounding_policy::nearest);
			context.decompress_tracks(writer);
			checksum += rotations[0] + translations[0];
		};
		if (opts.pose >= 0)
		{
			const uint32_t frame = pose_frame(opts, frames);
			sample(frame);
			print_pose("acl", clip, frame, joints, rotations.data(), translations.data());
			std::free(memory);
			return 0;
		}
		double modes[6];
		for (int mode = 0; mode < 3; ++mode)
			for (int cold = 0; cold < 2; ++cold)
				modes[2 * mode + cold] = time_mode(sample, frames, mode, cold != 0, opts.repeats);
		report("acl", clip, frames, joints, file.size(), file.size() + sizeof(context), median(opens), modes);
		std::free(memory);
		return checksum == checksum ? 0 : 1;
	}

	int usage(const char* program)
	{
		std::fprintf(stderr, "usage: %s MANIFEST [REPEATS] [--sample] [--pose FRAME]\n", program);
		return 2;
	}

	bool parse_count(const char* text, long low, long& out)
	{
		char* end = nullptr;
		const long value = std::strtol(text, &end, 10);
		if (end == text || *end != '\0' || value < low || value > 1000000000L)
			return false;
		out = value;
		return true;
	}

	bool readable(const std::string& path)
	{
		FILE* file = std::fopen(path.c_str(), "rb");
		if (!file)
			return false;
		std::fclose(file);
		return true;
	}

	// The manifest's clips, every line checked before anything is timed: false (and one line on stderr naming the
	// manifest's line) when a line is not two readable files.
	bool read_manifest(const char* manifest, std::vector<std::pair<std::string, std::string>>& clips)
	{
		FILE* file = std::fopen(manifest, "r");
		if (!file)
		{
			std::fprintf(stderr, "%s: cannot read the manifest\n", manifest);
			return false;
		}
		std::string line;
		bool ok = true;
		for (int number = 1, c = 0; ok && c != EOF; ++number)
		{
			line.clear();
			while ((c = std::fgetc(file)) != EOF && c != '\n')
				line.push_back(char(c));
			std::vector<std::string> fields;
			for (size_t at = 0; at < line.size();)
			{
				const size_t begin = line.find_first_not_of(" \t\r", at);
				if (begin == std::string::npos)
					break;
				const size_t end = std::min(line.find_first_of(" \t\r", begin), line.size());
				fields.push_back(line.substr(begin, end - begin));
				at = end;
			}
			if (fields.empty())
				continue;
			if (fields.size() != 2)
			{
				std::fprintf(stderr, "%s, line %d: expected two paths (an mcb-rot stream and an ACL buffer), got %zu "
					"fields\n", manifest, number, fields.size());
				ok = false;
			}
			else if (!readable(fields[0]) || !readable(fields[1]))
			{
				std::fprintf(stderr, "%s, line %d: cannot read %s\n", manifest, number,
					(readable(fields[0]) ? fields[1] : fields[0]).c_str());
				ok = false;
			}
			else
				clips.emplace_back(fields[0], fields[1]);
		}
		std::fclose(file);
		if (ok && clips.empty())
		{
			std::fprintf(stderr, "%s: no clip (expected lines of two paths: an mcb-rot stream and an ACL buffer)\n",
				manifest);
			ok = false;
		}
		return ok;
	}
}

int main(int argc, char** argv)
{
	options opts;
	const char* manifest = nullptr;
	bool have_repeats = false;
	for (int i = 1; i < argc; ++i)
	{
		const std::string arg = argv[i];
		long value = 0;
		if (arg == "--sample")
			opts.sample = true;
		else if (arg == "--pose" && i + 1 < argc && parse_count(argv[i + 1], 0, value))
		{
			opts.pose = value;
			++i;
		}
		else if (!arg.empty() && arg[0] == '-')
			return usage(argv[0]);
		else if (!manifest)
			manifest = argv[i];
		else if (!have_repeats && parse_count(argv[i], 1, value))
		{
			opts.repeats = int(value);
			have_repeats = true;
		}
		else
			return usage(argv[0]);
	}
	if (!manifest)
		return usage(argv[0]);
	std::vector<std::pair<std::string, std::string>> clips;
	if (!read_manifest(manifest, clips))
		return 2;
	int failures = 0;
	for (const auto& clip : clips)
	{
		if (bench_mcbrot(clip.first.c_str(), opts) != 0)
			++failures;  // named on stderr; ACL is not timed on it either, so both decoders' clips stay the same
		else
			failures += bench_acl(clip.second.c_str(), clip.first.c_str(), opts);
	}
	return failures ? 1 : 0;
}
