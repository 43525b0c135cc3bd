// scans_to_rawlog: a text file of laser scans with odometry increments -> an MRPT rawlog in the
// "actions-observations" (SensFrame) format that rbpf-slam and icp-slam read.
//
// Built by benchmarks/mrpt_peers.py against libmrpt-obs-dev (MRPT 2.x). Input, whitespace
// separated:
//   line 1:  beams aperture_rad sensor_yaw_rad max_range_m std_error_m a1 a2 a3 a4 min_std_xy
//            min_std_phi   (the odometry noise, MRPT's Gaussian motion model: std of x and y =
//            min_std_xy + a1 distance + a2 |turn|, of the heading = min_std_phi + a3 distance +
//            a4 |turn|, SI units)
//   then one line per scan:  stamp_s dx dy dtheta r_0 .. r_{beams-1}
// where (dx, dy, dtheta) is the odometry increment since the previous scan in the previous
// scan's frame, ranges go right to left, beam i at sensor_yaw - aperture/2 + i aperture/(beams-1)
// in the robot's frame (MRPT spreads the beams over the aperture from the first to the last, so
// a fan not centred on the robot's heading, e.g. 180 beams from -90 to +89 degrees, needs the
// sensor turned), and a range <= 0 marks a no-return reading (stored as invalid). Each scan becomes one CActionCollection (a
// CActionRobotMovement2D) followed by one CSensoryFrame (a CObservation2DRangeScan).
// The motion model is MRPT's Gaussian one, not Thrun's: a rawlog keeps the raw increment and
// the model, and the reader recomputes the distribution; Thrun's model is a set of random
// samples whose mean (what the SLAM apps use as odometry) is then off by a random amount, and
// icp-slam does not seed its generator, so its runs differed (aces: 0.48 to 2.7 m).
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/poses/CPose3D.h>
#include <mrpt/serialization/CArchive.h>

#include <cstdio>
#include <fstream>
#include <iostream>
#include <vector>

int main(int argc, char** argv)
{
	using namespace mrpt::obs;
	if (argc != 3)
	{
		std::cerr << "usage: " << argv[0] << " scans.txt out.rawlog\n";
		return 2;
	}
	std::ifstream in(argv[1]);
	size_t beams = 0;
	double aperture = 0, sensorYaw = 0, maxRange = 0, stdError = 0;
	double a1 = 0, a2 = 0, a3 = 0, a4 = 0, minStdXY = 0, minStdPhi = 0;
	if (!(in >> beams >> aperture >> sensorYaw >> maxRange >> stdError >> a1 >> a2 >> a3 >> a4 >>
		  minStdXY >> minStdPhi) ||
		beams < 2)
	{
		std::cerr << argv[1] << ": bad header\n";
		return 1;
	}
	CActionRobotMovement2D::TMotionModelOptions motion;
	motion.modelSelection = CActionRobotMovement2D::mmGaussian;
	motion.gaussianModel = {a1, a2, a3, a4, minStdXY, minStdPhi};

	mrpt::io::CFileGZOutputStream out(argv[2]);
	auto archive = mrpt::serialization::archiveFrom(out);
	std::vector<double> ranges(beams);
	double stamp, dx, dy, dtheta;
	size_t count = 0;
	while (in >> stamp >> dx >> dy >> dtheta)
	{
		for (auto& r : ranges)
			if (!(in >> r))
			{
				std::cerr << argv[1] << ": scan " << count << " is short\n";
				return 1;
			}
		const auto when = mrpt::Clock::fromDouble(stamp);

		CActionRobotMovement2D move;
		move.timestamp = when;
		move.computeFromOdometry(mrpt::poses::CPose2D(dx, dy, dtheta), motion);
		CActionCollection actions;
		actions.insert(move);

		auto scan = CObservation2DRangeScan::Create();
		scan->sensorLabel = "LASER";
		scan->timestamp = when;
		scan->aperture = static_cast<float>(aperture);
		scan->rightToLeft = true;
		scan->maxRange = static_cast<float>(maxRange);
		scan->stdError = static_cast<float>(stdError);
		scan->sensorPose = mrpt::poses::CPose3D(0, 0, 0, sensorYaw, 0, 0);
		scan->resizeScan(beams);
		for (size_t i = 0; i < beams; i++)
		{
			const bool valid = ranges[i] > 0 && ranges[i] < maxRange;
			scan->setScanRange(i, static_cast<float>(valid ? ranges[i] : maxRange));
			scan->setScanRangeValidity(i, valid);
		}
		CSensoryFrame frame;
		frame.insert(scan);

		archive << actions << frame;
		count++;
	}
	std::printf("%zu\n", count);
	return count ? 0 : 1;
}
